"""From a detected pole to a range-bearing measurement with its own uncertainty.

Bearing: from the mask's centre column, exact pinhole (atan((cx - u) / f)) or the 2024 thesis's linear form.
Range: power laws ``range = a * px^b`` of the rotated box's width and height (pixel sizes normalised to the
calibration's reference image width), chosen by the thesis's rule (width when the box is wider than an upright
pole, i.e. cut at the top or bottom, height otherwise) or fused by inverse variance when both are trustworthy.
Standard deviations come from the calibration residuals, so the filter's measurement noise comes from data.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from naoslam.camera import PinholeCamera
from naoslam.landmarks import PoleGeometry

#: Range choices: the thesis's rule, only one law, or inverse-variance fusion of both.
RANGE_METHODS = ("rule", "width", "height", "fused")


@dataclass(frozen=True)
class PowerLaw:
    """``range_m = a * x ** b``, with the relative (log-space) standard deviation of its residuals."""

    a: float
    b: float
    relative_std: float = 0.1

    def __call__(self, x: np.ndarray | float) -> np.ndarray | float:
        return self.a * np.power(np.asarray(x, dtype=float), self.b)


@dataclass(frozen=True)
class Measurement:
    """One landmark sighting: range (m), bearing (rad, left positive), class as signature, and their noise."""

    range_m: float
    bearing_rad: float
    signature: str
    confidence: float
    range_std: float
    bearing_std: float
    source: str = ""


@dataclass(frozen=True)
class RangeCalibration:
    """Fitted range laws and the facts needed to apply them to any image size."""

    width_law: PowerLaw
    height_law: PowerLaw
    reference_width_px: int = 640
    upright_ratio: float = 0.21
    ratio_tolerance: float = 0.25
    bearing_std_rad: float = math.radians(1.0)
    hfov_deg: float = 56.3
    colour_law: PowerLaw | None = None
    extra: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict) -> "RangeCalibration":
        laws = {k: PowerLaw(**data[k]) for k in ("width_law", "height_law")}
        colour = PowerLaw(**data["colour_law"]) if data.get("colour_law") else None
        rest = {k: v for k, v in data.items() if k not in ("width_law", "height_law", "colour_law")}
        return cls(**laws, colour_law=colour, **rest)

    def range_from_box(self, width_px: float, height_px: float, image_width: int,
                       method: str = "fused") -> tuple[float, float, str]:
        """Range (m), its standard deviation (m) and which size it used, from a rotated box measured in pixels."""
        if method not in RANGE_METHODS:
            raise ValueError(f"range method {method!r} is not one of {', '.join(RANGE_METHODS)}")
        scale = self.reference_width_px / image_width
        width, height = max(width_px * scale, 1.0), max(height_px * scale, 1.0)
        by_width = float(self.width_law(width)), self.width_law.relative_std
        by_height = float(self.height_law(height)), self.height_law.relative_std
        ratio = width / height
        if method == "width" or (method in ("rule", "fused") and ratio > self.upright_ratio * (1 + self.ratio_tolerance)):
            return by_width[0], by_width[0] * by_width[1], "width"
        if method == "height" or method == "rule" or ratio < self.upright_ratio * (1 - self.ratio_tolerance):
            return by_height[0], by_height[0] * by_height[1], "height"
        # Both sizes look like an upright, whole pole: combine the two log-range estimates by inverse variance.
        weights = np.array([1 / by_width[1] ** 2, 1 / by_height[1] ** 2])
        log_range = (weights @ np.log([by_width[0], by_height[0]])) / weights.sum()
        fused = float(np.exp(log_range))
        return fused, fused / math.sqrt(weights.sum()), "fused"


    def colour_range(self, band_distance_px: float, image_width: int,
                     geometry: PoleGeometry = PoleGeometry()) -> tuple[float, float]:
        """Range (m) and its standard deviation from the colour filter's band-centre distance (pixels)."""
        if self.colour_law is None:
            raise ValueError("this calibration has no colour law - calibrate with poles whose band distance is known")
        per_cm = band_distance_px * self.reference_width_px / image_width / (geometry.band_height * 100)
        range_m = float(self.colour_law(per_cm))
        return range_m, range_m * self.colour_law.relative_std


def bearing_of_column(column: float, image_width: int, hfov_deg: float, linear: bool = False) -> float:
    """Bearing (rad, left positive) of an image column: exact pinhole, or the thesis's linear approximation."""
    camera = PinholeCamera(image_width, image_width, hfov_deg)  # the image height does not enter the bearing
    return float(camera.linear_bearing_of_column(column) if linear else camera.bearing_of_column(column))


#: The thesis's confidence threshold for detections used in SLAM (YOLOv8s).
THESIS_CONF = 0.85


class MeasurementModel:
    """Turns front-end detections into measurements with a calibration (confidence threshold as the thesis: 0.85)."""

    def __init__(self, calibration: RangeCalibration, min_confidence: float = THESIS_CONF, range_method: str = "fused",
                 linear_bearing: bool = False):
        if range_method not in RANGE_METHODS:
            raise ValueError(f"range method {range_method!r} is not one of {', '.join(RANGE_METHODS)}")
        self.calibration = calibration
        self.min_confidence = min_confidence
        self.range_method = range_method
        self.linear_bearing = linear_bearing

    def measure(self, detections, image_width: int) -> list[Measurement]:
        """Measurements for detections (``naoslam.detector.Detection``) above the confidence threshold."""
        out = []
        for d in detections:
            if d.confidence < self.min_confidence or d.rotated_box is None:
                continue
            range_m, range_std, used = self.calibration.range_from_box(d.rotated_box.width, d.rotated_box.height,
                                                                       image_width, self.range_method)
            bearing = bearing_of_column(d.centre_column, image_width, self.calibration.hfov_deg, self.linear_bearing)
            out.append(Measurement(range_m, bearing, d.name, d.confidence, range_std,
                                   self.calibration.bearing_std_rad, used))
        return out
