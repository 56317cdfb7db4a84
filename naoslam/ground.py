"""What the camera's pose says about a detection: every pole stands on the floor and is shorter than the camera is
high, so its foot row fixes its distance and its pixel height must agree with that distance.

With the camera's height, pitch and roll (from the robot's joint angles), a mask's lowest row is the front edge of
the pole's base on the ground plane: intersecting that pixel's ray with the floor gives a range that does not
depend on the mask's width or on the top of the pole (a third range estimate, exact for an uncut pole). The
ground-plane gate rejects a detection whose foot lies above the horizon, whose top reaches above the horizon
(taller than the camera is high), or whose pixel height disagrees with a 0.42 m pole at the foot's distance.
Conventions as :mod:`naoslam.camera`; ranges and bearings relative to the camera (x forward, y left).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from naoslam.camera import CameraPose, PinholeCamera
from naoslam.landmarks import PoleGeometry

#: Default tolerance of the height check: measured / expected pixel height must lie within [1/(1+t), 1+t].
HEIGHT_TOLERANCE = 0.35
#: Rows a pole's top may reach above the horizon (pose error, mask bleed) before it counts as too tall.
HORIZON_MARGIN_PX = 6.0
#: Uncertainty of a mask's lowest row (px): a network's masks are upsampled from prototypes at a quarter of the
#: input's resolution.
FOOT_ROW_STD_PX = 2.0
#: Rows above the horizon kept when the front end runs on the band below it (pose error, a pole's top near it).
CROP_MARGIN_PX = 16
#: Rows above the frame's bottom within which a mask counts as cut by it.
BOTTOM_MARGIN_PX = 4
#: Beyond this the foot's ray meets the floor too flat to trust (or the foot is a far wall's base).
MAX_GROUND_RANGE_M = 15.0


@dataclass(frozen=True)
class Foot:
    """Where a mask's lowest point meets the floor: range to the pole's axis (m), bearing (rad), the foot row."""

    range_m: float
    bearing_rad: float
    row: float


def ground_plane_problem(pose: CameraPose) -> str | None:
    """Why a camera pose has no floor under it to measure on (None when it has): the camera must stand above the
    floor, its pitch and roll within +-90 deg."""
    limit = math.pi / 2
    if pose.z > 0 and abs(pose.pitch) < limit and abs(pose.roll) < limit:
        return None
    return (f"camera height {pose.z} m, pitch {pose.pitch:.3f} rad, roll {pose.roll:.3f} rad: the ground plane needs "
            "the camera above the floor and pitch and roll within +-90 deg")


@dataclass(frozen=True)
class GroundView:
    """A camera of known height, pitch and roll over a flat floor (``pose``'s x, y and yaw are ignored)."""

    camera: PinholeCamera
    pose: CameraPose
    pole: PoleGeometry = PoleGeometry()

    def __post_init__(self) -> None:
        problem = ground_plane_problem(self.pose)
        if problem:
            raise ValueError(f"{problem} - leave the pose out for this frame")

    @cached_property
    def _rotation(self) -> np.ndarray:
        return CameraPose(0.0, 0.0, self.pose.z, 0.0, self.pose.pitch, self.pose.roll).world_from_camera()

    def ground_point(self, u: float, v: float) -> np.ndarray | None:
        """(x, y) on the floor seen at pixel (u, v), or None when the ray does not go down to the floor."""
        ray = self._rotation @ self.camera.pixel_rays(u, v)
        if ray[2] >= -1e-9:
            return None
        t = self.pose.z / -ray[2]
        return np.array([t * ray[0], t * ray[1]])

    def pixels_per_metre(self, u: np.ndarray, v: np.ndarray, height_m: float) -> np.ndarray:
        """At each pixel (u, v), how many pixels one metre spans for an object there whose point at that pixel
        stands ``height_m`` above the floor: the focal length over the depth at which the pixel's ray meets that
        height. NaN where the ray does not come down to it in front of the camera (the object would float)."""
        rays = self.camera.pixel_rays(u, v) @ self._rotation.T
        drop = self.pose.z - height_m
        with np.errstate(divide="ignore", invalid="ignore"):
            depth = np.where(rays[..., 2] < -1e-9, drop / -rays[..., 2], np.nan)
        return np.where(depth > 0, self.camera.focal_px / depth, np.nan)

    def project(self, point: np.ndarray) -> np.ndarray | None:
        """Pixel (u, v) of a point (x, y, z) relative to the camera's ground position; None behind the camera."""
        in_camera = (np.asarray(point, float) - np.array([0.0, 0.0, self.pose.z])) @ self._rotation
        return None if in_camera[2] <= 1e-9 else self.camera.project(in_camera)

    @cached_property
    def _horizon(self) -> tuple[float, float, float] | None:
        """The horizon as a line through pixel (u0, v0) with slope dv/du; None when it is not in front of the camera."""
        far = self.project(np.array([1e6, 0.0, self.pose.z]))
        side = self.project(np.array([1e6, 1e5, self.pose.z]))
        if far is None or side is None or abs(side[0] - far[0]) < 1e-9:
            return None
        return float(far[0]), float(far[1]), float((side[1] - far[1]) / (side[0] - far[0]))

    def horizon_row(self, u: float) -> float:
        """Image row of the horizon at column ``u`` (where rays run level with the floor)."""
        if self._horizon is None:
            return -math.inf
        u0, v0, slope = self._horizon
        return v0 + (u - u0) * slope

    def band_top(self) -> int:
        """The first frame row where a pole can appear: ``CROP_MARGIN_PX`` above the horizon's highest point
        (a pole's top stays below the horizon), 0 when the horizon is above the frame."""
        highest = min(self.horizon_row(0.0), self.horizon_row(float(self.camera.width)))
        return int(np.clip(math.floor(highest - CROP_MARGIN_PX), 0, self.camera.height - 1))

    def reaches_bottom(self, extent: "PoleExtent") -> bool:
        """True when the pole comes within ``BOTTOM_MARGIN_PX`` of the frame's last row: the foot may lie below the
        frame (a network's mask, upsampled from its prototypes, can stop a few pixels short of the border)."""
        return extent.bottom[1] >= self.camera.height - BOTTOM_MARGIN_PX

    def foot(self, mask: np.ndarray, origin: tuple[int, int] = (0, 0)) -> Foot | None:
        """The pole's foot from its mask's lowest row (see :meth:`foot_of`)."""
        extent = PoleExtent.of_mask(mask, origin)
        return self.foot_of(extent) if extent is not None else None

    def foot_of(self, extent: "PoleExtent") -> Foot | None:
        """The pole's foot from its lowest point; None when the pole reaches the frame's bottom (the foot may be cut
        off), or the point's ray misses the floor or meets it too far away.

        The lowest silhouette point is the base circle's edge nearest the camera, so the axis lies one radius
        further along the same bearing.
        """
        if self.reaches_bottom(extent):
            return None
        u, v = extent.bottom
        point = self.ground_point(u, v)
        if point is None:
            return None
        front = float(np.hypot(*point))
        if front > MAX_GROUND_RANGE_M:
            return None
        return Foot(front + self.pole.radius, float(math.atan2(point[1], point[0])), v)

    def level_size(self, width_px: float, height_px: float, range_m: float,
                   bearing_rad: float) -> tuple[float, float]:
        """A pole's box size as a level, upright camera at the same height would see it at ``range_m`` and
        ``bearing_rad``: the size the range laws were fitted on. A camera pitched by p images what stands near the
        horizon about 1 / cos^2 p taller and 1 / cos p wider (8 deg: 2.0 % and 1.0 %) and a near pole below it
        shorter, which a level law reads as nearer or farther. Sizes are kept where the pole is behind either camera."""
        seen, flat = self._pole_size_px(range_m, bearing_rad), self._level._pole_size_px(range_m, bearing_rad)
        if seen is None or flat is None or min(*seen, *flat) <= 0:
            return width_px, height_px
        return width_px * flat[0] / seen[0], height_px * flat[1] / seen[1]

    @cached_property
    def _level(self) -> "GroundView":
        """The same camera at the same height, level and upright."""
        return GroundView(self.camera, CameraPose(z=self.pose.z), self.pole)

    def _pole_points_px(self, range_m: float, bearing_rad: float) -> list[np.ndarray] | None:
        """Pixels of an upright pole whose axis stands at ``range_m``, ``bearing_rad``: its base's near edge, its
        top's far edge (the camera looks down on the top), and its left and right edges at half its height; None
        when a point is behind the camera."""
        along = np.array([math.cos(bearing_rad), math.sin(bearing_rad), 0.0])
        across = np.array([-along[1], along[0], 0.0])
        radius, height = self.pole.radius, np.array([0.0, 0.0, self.pole.height])
        axis = range_m * along
        points = np.array([axis - radius * along, axis + radius * along + height,
                           axis + height / 2 - radius * across, axis + height / 2 + radius * across])
        in_camera = (points - np.array([0.0, 0.0, self.pose.z])) @ self._rotation
        return None if (in_camera[:, 2] <= 1e-9).any() else list(self.camera.project(in_camera))

    def _pole_size_px(self, range_m: float, bearing_rad: float) -> tuple[float, float] | None:
        """Pixel width (across the pole at half its height) and length (base's near edge to top's far edge) of an
        upright pole at ``range_m``, ``bearing_rad``; None when a point is behind the camera."""
        points = self._pole_points_px(range_m, bearing_rad)
        if points is None:
            return None
        base, top, left, right = points
        return float(np.hypot(*(right - left))), float(np.hypot(*(top - base)))

    def expected_height_px(self, foot: Foot) -> float:
        """Pixel height of a whole upright pole standing at ``foot``: from its base's near edge to its top's far
        edge (the camera looks down on the top)."""
        points = self._pole_points_px(foot.range_m, foot.bearing_rad)
        if points is None:
            return math.nan
        base, top = points[:2]
        return float(base[1] - top[1])

    def foot_range_std(self, foot: Foot, pixel_std: float = FOOT_ROW_STD_PX,
                       pitch_std_rad: float = math.radians(0.5)) -> float:
        """Standard deviation (m) of the foot-row range: the foot row's and the pitch's uncertainty, through
        d range / d angle = range^2 / height."""
        angle_std = math.hypot(pixel_std / self.camera.focal_px, pitch_std_rad)
        return foot.range_m ** 2 / self.pose.z * angle_std

    def check(self, mask: np.ndarray, origin: tuple[int, int] = (0, 0),
              tolerance: float = HEIGHT_TOLERANCE) -> str | None:
        """Why this mask cannot be a pole standing on the floor, or None when it can (see :meth:`check_extent`)."""
        extent = PoleExtent.of_mask(mask, origin)
        return self.check_extent(extent, tolerance) if extent is not None else "empty mask"

    def check_extent(self, extent: "PoleExtent", tolerance: float = HEIGHT_TOLERANCE) -> str | None:
        """Why a pole with this top and foot cannot stand on the floor, or None when it can."""
        top_column, top_row = extent.top
        if top_row < self.horizon_row(top_column) - HORIZON_MARGIN_PX:
            return "reaches above the horizon: taller than the camera is high"
        if self.reaches_bottom(extent):
            return None  # the foot may be below the frame: nothing more to check
        foot = self.foot_of(extent)
        if foot is None:
            return "foot above the horizon"
        expected = self.expected_height_px(foot)
        measured = foot.row - top_row
        cut_at_top = top_row <= 0
        if measured > expected * (1 + tolerance) or (not cut_at_top and measured < expected / (1 + tolerance)):
            return f"{measured:.0f} px tall where a pole at {foot.range_m:.1f} m is {expected:.0f} px"
        return None


def ground_gate(view: GroundView, detections: list) -> tuple[list, list[tuple[object, str]]]:
    """The detections (anything with an ``extent``) that can stand on the floor, and (detection, reason) for those
    that cannot."""
    kept, rejected = [], []
    for detection in detections:
        extent = detection.extent
        reason = view.check_extent(extent) if extent is not None else "empty mask"
        if reason is None:
            kept.append(detection)
        else:
            rejected.append((detection, reason))
    return kept, rejected


@dataclass(frozen=True)
class PoleExtent:
    """A pole's highest and lowest image points (u, v): the middle of its first row at that row's top, and the
    middle of its last row at that row's lower edge, where the base meets the floor."""

    top: tuple[float, float]
    bottom: tuple[float, float]

    @classmethod
    def of_mask(cls, mask: np.ndarray, origin: tuple[int, int] = (0, 0)) -> "PoleExtent | None":
        """The extent of a mask whose (0, 0) lies at ``origin`` (x, y) of the frame; None for an empty mask."""
        rows = np.flatnonzero(mask.any(axis=1))
        if not len(rows):
            return None
        top_column = origin[0] + float(np.flatnonzero(mask[rows[0]]).mean()) + 0.5
        bottom_column = origin[0] + float(np.flatnonzero(mask[rows[-1]]).mean()) + 0.5
        return cls((top_column, float(origin[1] + rows[0])), (bottom_column, float(origin[1] + rows[-1] + 1)))

    @classmethod
    def of_box(cls, box: tuple[float, float, float, float]) -> "PoleExtent":
        """The extent of an upright pole's box (x0, y0, x1, y1): the middle of its top and bottom edges."""
        x0, y0, x1, y1 = box
        return cls(((x0 + x1) / 2, float(y0)), ((x0 + x1) / 2, float(y1)))
