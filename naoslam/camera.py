"""Pinhole model of the Nao top camera and its pose in the world.

Conventions: world x forward, y left, z up (metres); camera optical frame x right, y down, z forward;
pixel (u, v) measured from the top-left corner of the image, so the centre of pixel (col, row) is (col + 0.5, row + 0.5).
"""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, fields

import numpy as np

#: Horizontal field of view of the Nao v6 top camera measured in the 2024 thesis (Aldebaran documents 60.97 deg).
NAO_HFOV_DEG = 56.3


def finite_numbers(*values) -> bool:
    """Whether every value is a real, finite number (not None, text, NaN or infinity)."""
    return all(isinstance(v, numbers.Real) and math.isfinite(v) for v in values)


@dataclass(frozen=True)
class PinholeCamera:
    """Intrinsics of an undistorted pinhole camera with square pixels and the principal point at the centre."""

    width: int = 640
    height: int = 480
    hfov_deg: float = NAO_HFOV_DEG

    def __post_init__(self) -> None:
        for name in ("width", "height"):
            value = getattr(self, name)
            if not (finite_numbers(value) and value > 0):
                raise ValueError(f"image {name} {value!r}: give the frame's size in pixels, width frame.shape[1] and "
                                 "height frame.shape[0]")
        if not (finite_numbers(self.hfov_deg) and 0 < self.hfov_deg < 180):
            raise ValueError(f"field of view {self.hfov_deg!r} deg: give the camera's horizontal field of view in "
                             f"degrees, between 0 and 180 (the Nao's top camera: {NAO_HFOV_DEG})")

    @property
    def focal_px(self) -> float:
        """Focal length in pixels, from the horizontal field of view."""
        return (self.width / 2.0) / math.tan(math.radians(self.hfov_deg) / 2.0)

    @property
    def cx(self) -> float:
        return self.width / 2.0

    @property
    def cy(self) -> float:
        return self.height / 2.0

    def bearing_of_column(self, u: np.ndarray | float) -> np.ndarray | float:
        """Exact pinhole bearing (rad) of an image column for an upright camera: left of centre is positive."""
        return np.arctan((self.cx - np.asarray(u, dtype=float)) / self.focal_px)

    def linear_bearing_of_column(self, u: np.ndarray | float) -> np.ndarray | float:
        """The 2024 thesis's linear bearing (rad): -(u - cx) * HFOV / width."""
        return -(np.asarray(u, dtype=float) - self.cx) * math.radians(self.hfov_deg) / self.width

    def pixel_rays(self, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Unnormalised ray directions (..., 3) in the camera frame through pixel coordinates (u, v)."""
        f = self.focal_px
        u = np.asarray(u, dtype=np.float64)
        v = np.asarray(v, dtype=np.float64)
        return np.stack([(u - self.cx) / f, (v - self.cy) / f, np.ones(np.broadcast(u, v).shape)], axis=-1)

    def project(self, points_cam: np.ndarray) -> np.ndarray:
        """Pixel coordinates (..., 2) of points (..., 3) in the camera frame (z must be positive)."""
        p = np.asarray(points_cam, dtype=np.float64)
        f = self.focal_px
        return np.stack([f * p[..., 0] / p[..., 2] + self.cx, f * p[..., 1] / p[..., 2] + self.cy], axis=-1)


def _rot_x(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _rot_y(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rot_z(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


# Camera axes expressed in the world for yaw = pitch = roll = 0: optical x -> world -y, y -> -z, z -> +x.
_OPTICAL_IN_BODY = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


@dataclass(frozen=True)
class CameraPose:
    """Where the camera is: position (m) and yaw / pitch (down is positive) / roll (rad)."""

    x: float = 0.0
    y: float = 0.0
    z: float = 0.50
    yaw: float = 0.0
    pitch: float = 0.0
    roll: float = 0.0

    def __post_init__(self) -> None:
        bad = {f.name: getattr(self, f.name) for f in fields(self) if not math.isfinite(getattr(self, f.name))}
        if bad:
            raise ValueError(f"camera pose {bad} is not finite - leave the pose out for this frame (no ground-plane "
                             "gate, no foot-row range) rather than pass a joint reading that failed")

    @property
    def position(self) -> np.ndarray:
        return np.array([self.x, self.y, self.z])

    def world_from_camera(self) -> np.ndarray:
        """Rotation matrix taking camera-frame vectors to world-frame vectors."""
        return _rot_z(self.yaw) @ _rot_y(self.pitch) @ _rot_x(self.roll) @ _OPTICAL_IN_BODY

    def to_camera(self, points_world: np.ndarray) -> np.ndarray:
        """World points (..., 3) expressed in the camera frame."""
        return (np.asarray(points_world, dtype=np.float64) - self.position) @ self.world_from_camera()

    def range_bearing_to(self, x: float, y: float) -> tuple[float, float]:
        """Horizontal range (m) and bearing (rad, left positive) from the camera to a point on the ground."""
        dx, dy = x - self.x, y - self.y
        bearing = math.atan2(dy, dx) - self.yaw
        return math.hypot(dx, dy), math.atan2(math.sin(bearing), math.cos(bearing))
