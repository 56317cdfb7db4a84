"""Exact ray casting of cylinders and quads through the pinhole camera (depth = camera-frame z)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from detector.synth.objects import Cylinder, Quad
from naoslam.camera import CameraPose, PinholeCamera

#: Objects closer than this to the camera plane (m) are not drawn.
NEAR_PLANE = 0.05
#: Brightness of the inside of a tube, seen through its open end.
INSIDE_SHADE = 0.35


@dataclass(frozen=True)
class Lighting:
    """A directional light (unit vector towards the light) plus ambient light."""

    direction: np.ndarray
    ambient: float = 0.45
    diffuse: float = 0.65

    def shade(self, normals: np.ndarray) -> np.ndarray:
        """Lambertian brightness for unit normals (..., 3)."""
        return self.ambient + self.diffuse * np.clip(normals @ self.direction, 0.0, None)


@dataclass
class Hit:
    """What one object covers inside pixel box [u0, u1) x [v0, v1): coverage, depth and shaded colour.

    ``axial`` (cylinders only) is the height along the axis of the surface each pixel shows, so a pixel's band is known.
    """

    u0: int
    v0: int
    mask: np.ndarray
    depth: np.ndarray
    colour: np.ndarray
    axial: np.ndarray | None = None

    def band_pixels(self, z0: float, z1: float) -> int:
        """How many covered pixels show axis heights z0..z1."""
        return int((self.mask & (self.axial >= z0) & (self.axial <= z1)).sum())


def pixel_box(points_world: np.ndarray, pose: CameraPose, camera: PinholeCamera, clip: bool) -> tuple[int, int, int, int] | None:
    """Integer pixel box (u0, v0, u1, v1) around the projection of ``points_world``; None if behind the camera."""
    cam = pose.to_camera(points_world)
    if np.any(cam[:, 2] < NEAR_PLANE):
        return None
    uv = camera.project(cam)
    u0, v0 = np.floor(uv.min(axis=0)).astype(int) - 1
    u1, v1 = np.ceil(uv.max(axis=0)).astype(int) + 1
    if clip:
        u0, v0, u1, v1 = max(u0, 0), max(v0, 0), min(u1, camera.width), min(v1, camera.height)
    return (u0, v0, u1, v1) if u1 > u0 and v1 > v0 else None


def world_rays(box: tuple[int, int, int, int], pose: CameraPose, camera: PinholeCamera) -> np.ndarray:
    """Ray directions (h, w, 3) in the world through the pixel centres of ``box``; scaled so camera z = 1."""
    u0, v0, u1, v1 = box
    u, v = np.meshgrid(np.arange(u0, u1) + 0.5, np.arange(v0, v1) + 0.5)
    return camera.pixel_rays(u, v) @ pose.world_from_camera().T


def cast_cylinder(cylinder: Cylinder, pose: CameraPose, camera: PinholeCamera, lighting: Lighting,
                  clip: bool = True) -> Hit | None:
    """Pixels whose ray passes through the tube's outer wall, or through an open end onto its inner wall."""
    box = pixel_box(cylinder.corners(), pose, camera, clip)
    if box is None:
        return None
    rays = world_rays(box, pose, camera) @ cylinder.rotation
    origin = (pose.position - cylinder.base) @ cylinder.rotation
    dx, dy, dz = rays[..., 0], rays[..., 1], rays[..., 2]
    a = dx * dx + dy * dy
    b = 2.0 * (origin[0] * dx + origin[1] * dy)
    c = origin[0] ** 2 + origin[1] ** 2 - cylinder.radius ** 2
    disc = b * b - 4.0 * a * c
    ok = (disc >= 0) & (a > 1e-12)
    root = np.sqrt(np.where(ok, disc, 0.0))
    safe_a = np.where(ok, a, 1.0)
    t_near, t_far = (-b - root) / (2 * safe_a), (-b + root) / (2 * safe_a)
    z_near, z_far = origin[2] + t_near * dz, origin[2] + t_far * dz
    outer = ok & (t_near > 0) & (z_near >= 0) & (z_near <= cylinder.length)
    inner = ok & ~outer & (t_far > 0) & (z_far >= 0) & (z_far <= cylinder.length)
    mask = outer | inner
    if not mask.any():
        return None
    t = np.where(outer, t_near, t_far)
    z = np.where(outer, z_near, z_far)
    hit_x, hit_y = origin[0] + t * dx, origin[1] + t * dy
    normals_local = np.stack([hit_x, hit_y, np.zeros_like(hit_x)], axis=-1) / cylinder.radius
    brightness = np.where(outer, lighting.shade(normals_local @ cylinder.rotation.T), lighting.ambient * INSIDE_SHADE)
    colour = np.zeros(mask.shape + (3,), np.float32)
    for z0, z1, rgb in cylinder.bands:
        colour[(z >= z0) & (z <= z1)] = rgb
    colour *= brightness[..., None]
    return Hit(box[0], box[1], mask, np.where(mask, t, np.inf), colour, z)


def cast_quad(quad: Quad, pose: CameraPose, camera: PinholeCamera, lighting: Lighting) -> Hit | None:
    """Pixels whose ray meets the rectangle, coloured from its texture (nearest texel), flat shaded."""
    box = pixel_box(quad.corners(), pose, camera, clip=True)
    if box is None:
        return None
    rays = world_rays(box, pose, camera)
    normal = np.cross(quad.axis_u, quad.axis_v)
    denom = rays @ normal
    with np.errstate(divide="ignore", invalid="ignore"):
        t = ((quad.centre - pose.position) @ normal) / denom
    offset = pose.position + t[..., None] * rays - quad.centre
    a, b = offset @ quad.axis_u, offset @ quad.axis_v
    mask = np.isfinite(t) & (t > 0) & (np.abs(a) <= quad.half_u) & (np.abs(b) <= quad.half_v)
    if not mask.any():
        return None
    th, tw = quad.texture.shape[:2]
    cols = np.clip(((a / quad.half_u + 1) * 0.5 * tw).astype(int), 0, tw - 1)
    rows = np.clip(((b / quad.half_v + 1) * 0.5 * th).astype(int), 0, th - 1)
    brightness = lighting.ambient + lighting.diffuse * abs(float(normal @ lighting.direction))
    colour = quad.texture[rows, cols].astype(np.float32) * brightness
    return Hit(box[0], box[1], mask, np.where(mask, t, np.inf), colour)
