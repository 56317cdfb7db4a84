"""The world behind the objects: the carpet with the SPL field lines, the floor, the room's walls and ceiling."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from detector.synth.objects import RGB
from detector.synth.raycast import Lighting
from naoslam.field import FieldGeometry


@dataclass(frozen=True)
class WallFeature:
    """A rectangle painted on wall ``wall`` (0: +x, 1: -x, 2: +y, 3: -y), from u0..u1 along it and z0..z1 up.

    ``emissive`` features (windows with daylight behind) are not shaded and may be brighter than white.
    """

    wall: int
    u0: float
    u1: float
    z0: float
    z1: float
    rgb: RGB
    emissive: bool = False


@dataclass
class Room:
    """Field-centred room box with its surfaces' colours and what hangs on its walls."""

    x_min: float
    x_max: float
    y_min: float
    y_max: float
    height: float
    wall_rgb: tuple[RGB, RGB, RGB, RGB]
    carpet_rgb: RGB
    floor_rgb: RGB
    ceiling_rgb: RGB
    line_rgb: RGB = (0.92, 0.93, 0.92)
    features: list[WallFeature] = field(default_factory=list)


def field_line_mask(x: np.ndarray, y: np.ndarray, f: FieldGeometry) -> np.ndarray:
    """True where a ground point (field coordinates) lies on a painted field line."""
    w = f.line_width / 2.0
    ax, ay = np.abs(x), np.abs(y)
    half_l, half_w = f.length / 2.0, f.width / 2.0
    inside = (ax <= half_l + w) & (ay <= half_w + w)
    on = inside & ((np.abs(ax - half_l) <= w) | (np.abs(ay - half_w) <= w) | (ax <= w))
    on |= np.abs(np.hypot(x, y) - f.centre_circle_radius) <= w
    for depth, half_span in ((f.penalty_area_length, f.penalty_area_width / 2), (f.goal_area_length, f.goal_area_width / 2)):
        front = half_l - depth
        on |= (np.abs(ax - front) <= w) & (ay <= half_span + w)
        on |= (np.abs(ay - half_span) <= w) & (ax >= front) & (ax <= half_l)
    for mark_x in (0.0, half_l - f.penalty_mark_distance):
        near = np.abs(ax - mark_x)
        on |= ((near <= 0.05) & (ay <= w)) | ((near <= w) & (ay <= 0.05))
    return on


def render_background(origin: np.ndarray, rays: np.ndarray, room: Room, lighting: Lighting,
                      geometry: FieldGeometry = FieldGeometry()) -> tuple[np.ndarray, np.ndarray]:
    """Colour (h, w, 3) and depth (h, w) of the room for world rays (h, w, 3) scaled to camera depth 1."""
    shape = rays.shape[:2]
    colour = np.empty(shape + (3,), np.float32)
    colour[:] = room.ceiling_rgb
    dx, dy, dz = rays[..., 0], rays[..., 1], rays[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        candidates = [((room.x_max - origin[0]) / dx, dx > 0), ((room.x_min - origin[0]) / dx, dx < 0),
                      ((room.y_max - origin[1]) / dy, dy > 0), ((room.y_min - origin[1]) / dy, dy < 0)]
        t_walls = np.stack([np.where(valid, t, np.inf) for t, valid in candidates])
        wall = np.argmin(t_walls, axis=0)
        t_wall = np.take_along_axis(t_walls, wall[None], 0)[0]
        t_ground = np.where(dz < 0, -origin[2] / dz, np.inf)
    ground = t_ground < t_wall
    _paint_ground(colour, ground, origin, rays, t_ground, room, lighting, geometry)
    z_wall = origin[2] + t_wall * dz
    on_wall = ~ground & (z_wall <= room.height)
    _paint_walls(colour, on_wall, wall, origin, rays, t_wall, z_wall, room, lighting)
    return colour, np.where(ground, t_ground, t_wall).astype(np.float32)


def _paint_ground(colour, ground, origin, rays, t, room: Room, lighting: Lighting, geometry: FieldGeometry) -> None:
    gx = origin[0] + t[ground] * rays[..., 0][ground]
    gy = origin[1] + t[ground] * rays[..., 1][ground]
    on_carpet = (np.abs(gx) <= geometry.length / 2 + geometry.border) & (np.abs(gy) <= geometry.width / 2 + geometry.border)
    texture = 1.0 + 0.05 * np.sin(gx * 7.3 + np.sin(gy * 3.1)) * np.sin(gy * 5.7 + 1.3)
    rgb = np.where(on_carpet[:, None], np.array(room.carpet_rgb, np.float32), np.array(room.floor_rgb, np.float32))
    rgb = np.where(field_line_mask(gx, gy, geometry)[:, None], np.array(room.line_rgb, np.float32), rgb)
    brightness = lighting.ambient + lighting.diffuse * max(float(lighting.direction[2]), 0.0)
    colour[ground] = rgb * (texture * brightness)[:, None]


def _paint_walls(colour, on_wall, wall, origin, rays, t, z, room: Room, lighting: Lighting) -> None:
    w = wall[on_wall]
    along = np.where(w < 2, origin[1] + t[on_wall] * rays[..., 1][on_wall], origin[0] + t[on_wall] * rays[..., 0][on_wall])
    height = z[on_wall]
    rgb = np.array(room.wall_rgb, np.float32)[w]
    normals = np.array([[-1, 0, 0], [1, 0, 0], [0, -1, 0], [0, 1, 0]], np.float32)
    brightness = lighting.ambient + lighting.diffuse * 0.6 * np.clip(normals @ lighting.direction, 0, None)
    shade = np.asarray(brightness, np.float32)[w]
    for feature in room.features:
        inside = (w == feature.wall) & (along >= feature.u0) & (along <= feature.u1) & (height >= feature.z0) & (height <= feature.z1)
        rgb[inside] = feature.rgb
        if feature.emissive:
            shade[inside] = 1.0
    colour[on_wall] = rgb * shade[:, None]
