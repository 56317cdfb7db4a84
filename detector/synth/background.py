"""The world behind the objects: the carpet with the SPL field lines, the floor, the room's walls and ceiling.

Surfaces are not flat colours: the carpet has a pile and walls and floor a texture, from grey photographs that
scikit-image ships (brick, gravel, grass; nothing is downloaded), laid in world coordinates so they shrink with
distance and follow the perspective.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

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
    #: Texture photo per wall (a name of ``surface_photos``, None: plain paint), its tile size (m) and strength.
    wall_texture: tuple[str | None, str | None, str | None, str | None] = (None, None, None, None)
    floor_texture: str | None = None
    texture_tile_m: float = 1.0
    texture_strength: float = 0.0
    #: Strength of the carpet's pile (the grass photo, tiled every 0.5 m).
    carpet_pile: float = 0.0


#: Tile size of the carpet's pile (m).
PILE_TILE_M = 0.5


@lru_cache(maxsize=1)
def surface_photos() -> dict[str, np.ndarray]:
    """scikit-image's grey texture photos, each scaled to mean 1 (multiplies a surface's colour)."""
    import skimage.data  # deferred: the photos load only when a rendered room is drawn

    photos = {name: getattr(skimage.data, name)().astype(np.float32) for name in ("brick", "gravel", "grass")}
    return {name: photo / photo.mean() for name, photo in photos.items()}


def texture_gain(name: str, u: np.ndarray, v: np.ndarray, tile_m: float, strength: float) -> np.ndarray:
    """The photo ``name`` tiled every ``tile_m`` metres over surface coordinates (u, v), bilinear, as a brightness
    gain around 1 whose contrast is ``strength`` times the photo's."""
    photo = surface_photos()[name]
    size = photo.shape[0]
    x, y = np.mod(u / tile_m * size, size), np.mod(v / tile_m * size, size)
    x0, y0 = x.astype(np.int64) % size, y.astype(np.int64) % size
    fx, fy = (x - np.floor(x)).astype(np.float32), (y - np.floor(y)).astype(np.float32)
    x1, y1 = (x0 + 1) % size, (y0 + 1) % size
    value = (photo[y0, x0] * (1 - fx) + photo[y0, x1] * fx) * (1 - fy) + (photo[y1, x0] * (1 - fx) + photo[y1, x1] * fx) * fy
    return 1.0 + strength * (value - 1.0)


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
    if room.carpet_pile > 0:
        texture = np.where(on_carpet, texture * texture_gain("grass", gx, gy, PILE_TILE_M, room.carpet_pile), texture)
    if room.floor_texture is not None:
        floor_gain = texture_gain(room.floor_texture, gx, gy, room.texture_tile_m, room.texture_strength)
        texture = np.where(on_carpet, texture, texture * floor_gain)
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
    for index, name in enumerate(room.wall_texture):
        textured = w == index
        if name is not None and textured.any():
            shade[textured] *= texture_gain(name, along[textured], height[textured], room.texture_tile_m,
                                            room.texture_strength)
    for feature in room.features:
        inside = (w == feature.wall) & (along >= feature.u0) & (along <= feature.u1) & (height >= feature.z0) & (height <= feature.z1)
        rgb[inside] = feature.rgb
        if feature.emissive:
            shade[inside] = 1.0
    colour[on_wall] = rgb * shade[:, None]
