"""From a detected pole to a range-bearing measurement with its own uncertainty.

Bearing: from the mask's centre column, exact pinhole (atan((cx - u) / f)) or the 2024 thesis's linear form.
Range: power laws ``range = a * px^b`` of the rotated box's width and height (pixel sizes normalised to the
calibration's reference image width and, for calibrations fitted so, to the size the pole would have on the optical
axis: a pinhole camera stretches a pole off to the side, see :func:`on_axis_size`), chosen by the thesis's rule
(width when the box is wider than an upright pole, i.e. cut at the top or bottom, height otherwise) or fused by
inverse variance when both are trustworthy. Standard deviations come from the calibration (its residuals, at least a
walking robot's noise), so the filter's measurement noise comes from data.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace

import numpy as np

from naoslam.camera import NAO_HFOV_DEG, CameraPose, PinholeCamera, finite_numbers
from naoslam.ground import GroundView
from naoslam.landmarks import PoleGeometry

#: Range choices: the thesis's rule, only one law, or inverse-variance fusion of both.
RANGE_METHODS = ("rule", "width", "height", "fused")


@dataclass(frozen=True)
class PowerLaw:
    """``range_m = a * x ** b``, with the relative (log-space) standard deviation of its residuals."""

    a: float
    b: float
    relative_std: float = 0.1

    def __post_init__(self) -> None:
        if not (finite_numbers(self.a, self.b, self.relative_std) and self.a > 0 and self.relative_std >= 0):
            raise ValueError(f"range law {self.a!r} * px ** {self.b!r} (relative s.d. {self.relative_std!r}): a must "
                             "be above 0, b finite and the s.d. not negative - refit it with `poles calibrate`")

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
    #: The detection it was measured from (``naoslam.perception.detections.Detection``), if any.
    detection: object | None = field(default=None, compare=False, repr=False)
    #: A "maybe": seen below the operating threshold, so a filter takes it only where it confirms a mapped landmark
    #: of its class inside the gate, never to start one.
    tentative: bool = False

    def __post_init__(self) -> None:
        values = (self.range_m, self.bearing_rad, self.range_std, self.bearing_std)
        if not all(math.isfinite(v) for v in values) or self.range_m <= 0 or min(self.range_std, self.bearing_std) < 0:
            raise ValueError(f"measurement of {self.signature!r}: range {self.range_m} m, bearing {self.bearing_rad} "
                             f"rad, noise {self.range_std} m / {self.bearing_std} rad - the range must be positive, "
                             "the noise not negative, all four finite")


@dataclass(frozen=True)
class RangeCalibration:
    """Fitted range laws and the facts needed to apply them to any image size."""

    width_law: PowerLaw
    height_law: PowerLaw
    reference_width_px: int = 640
    upright_ratio: float = 0.21
    ratio_tolerance: float = 0.25
    bearing_std_rad: float = math.radians(1.0)
    hfov_deg: float = NAO_HFOV_DEG
    colour_law: PowerLaw | None = None
    extra: dict = field(default_factory=dict)
    #: Whether the laws were fitted on on-axis sizes (:func:`on_axis_size`); a calibration that says False was not.
    off_axis_corrected: bool = False
    #: Whether the colour law was fitted on on-axis band distances.
    colour_off_axis_corrected: bool = False
    #: The network input width whose masks the laws were fitted to: a model's masks, and so its pixel sizes, change
    #: with it. None: fitted on label masks, or not recorded (not checked).
    input_width: int | None = None

    def __post_init__(self) -> None:
        if not (finite_numbers(self.reference_width_px, self.bearing_std_rad, self.hfov_deg)
                and self.reference_width_px > 0 and self.bearing_std_rad >= 0 and 0 < self.hfov_deg < 180):
            raise ValueError(f"calibration for {self.reference_width_px!r} px wide frames, bearing s.d. "
                             f"{self.bearing_std_rad!r} rad, field of view {self.hfov_deg!r} deg: the width must be "
                             "above 0, the s.d. not negative and the field of view 0-180 deg - refit it with `poles "
                             "calibrate`")

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict) -> "RangeCalibration":
        """The calibration from its ``to_dict`` form (as stored in calibration.json and the ONNX metadata)."""
        laws = {k: PowerLaw(**data[k]) for k in ("width_law", "height_law")}
        colour = PowerLaw(**data["colour_law"]) if data.get("colour_law") else None
        rest = {k: v for k, v in data.items() if k not in ("width_law", "height_law", "colour_law")}
        return cls(**laws, colour_law=colour, **rest)

    def range_from_box(self, width_px: float, height_px: float, image_width: int, method: str = "fused",
                       column: float | None = None) -> tuple[float, float, str]:
        """Range (m), its standard deviation (m) and which size it used, from a rotated box measured in pixels;
        ``column``, the pole's centre column, undoes the off-axis stretch where the calibration was fitted so."""
        if method not in RANGE_METHODS:
            raise ValueError(f"range method {method!r} is not one of {', '.join(RANGE_METHODS)}")
        if self.off_axis_corrected and column is not None:
            width_px, height_px = on_axis_size(width_px, height_px, column, image_width, self.hfov_deg)
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


    def colour_range(self, band_distance_px: float, image_width: int, geometry: PoleGeometry = PoleGeometry(),
                     column: float | None = None) -> tuple[float, float]:
        """Range (m) and its standard deviation from the colour filter's band-centre distance (pixels); ``column``,
        the pole's centre column, undoes the off-axis stretch where the colour law was fitted so."""
        if self.colour_law is None:
            raise ValueError("this calibration has no colour law - calibrate with poles whose band distance is known")
        hfov_deg = self.hfov_deg if self.colour_off_axis_corrected else None
        per_cm = band_spacing_per_cm(band_distance_px, image_width, self.reference_width_px, geometry, column, hfov_deg)
        range_m = float(self.colour_law(per_cm))
        return range_m, range_m * self.colour_law.relative_std


def on_axis_size(width_px: float, height_px: float, column: float, image_width: int,
                 hfov_deg: float) -> tuple[float, float]:
    """A pole's box size as it would be on the optical axis at the same range. A pinhole camera images a pole at
    bearing t wider by 1 / cos^2 t (the image plane is flat) and taller by 1 / cos t (its depth is range * cos t):
    at the edge of the Nao's 56.3 deg view a pole looks 29 % wider, which a law fitted on-axis reads as ~20 % nearer."""
    cos_t = off_axis_cos(column, image_width, hfov_deg)
    return width_px * cos_t * cos_t, height_px * cos_t


def off_axis_cos(column: float, image_width: int, hfov_deg: float) -> float:
    """cos of the bearing of an image column: a vertical length there (a pole's height, the distance between its
    bands) times it is the length the pole would show on the optical axis at the same range."""
    return math.cos(bearing_of_column(column, image_width, hfov_deg))


def band_spacing_per_cm(band_distance_px: float, image_width: int, reference_width_px: int,
                        geometry: PoleGeometry = PoleGeometry(), column: float | None = None,
                        hfov_deg: float | None = None) -> float:
    """The colour law's input: the colour filter's band-centre distance in px per cm of band spacing, at the
    reference image width and, given the pole's column and the camera's ``hfov_deg``, on the optical axis."""
    if column is not None and hfov_deg is not None:
        band_distance_px *= off_axis_cos(column, image_width, hfov_deg)
    return band_distance_px * reference_width_px / image_width / (geometry.band_height * 100)


def bearing_of_column(column: float, image_width: int, hfov_deg: float, linear: bool = False) -> float:
    """Bearing (rad, left positive) of an image column: exact pinhole, or the thesis's linear approximation."""
    camera = PinholeCamera(image_width, image_width, hfov_deg)  # the image height does not enter the bearing
    return float(camera.linear_bearing_of_column(column) if linear else camera.bearing_of_column(column))


#: Standard deviations by which the foot-row and box ranges may differ before the foot is distrusted.
FOOT_AGREEMENT_SIGMAS = 3.0


def fuse_with_foot(box_range: float, box_std: float, foot_range: float,
                   foot_std: float) -> tuple[float, float] | None:
    """The box and foot-row ranges combined by inverse variance, or None when they disagree by more than
    ``FOOT_AGREEMENT_SIGMAS``: then the mask's lowest row is not the foot (hidden behind a robot or a ball) and
    only the box range should be used."""
    if abs(box_range - foot_range) > FOOT_AGREEMENT_SIGMAS * math.hypot(box_std, foot_std):
        return None
    weights = np.array([1 / box_std ** 2, 1 / foot_std ** 2])
    return float(weights @ [box_range, foot_range] / weights.sum()), 1 / math.sqrt(weights.sum())


#: The thesis's confidence threshold for detections used in SLAM (YOLOv8s).
THESIS_CONF = 0.85


class MeasurementModel:
    """Turns front-end detections into measurements with a calibration (confidence threshold as the thesis: 0.85).

    With the camera's pose, the box is first taken to the size a level camera would see
    (:meth:`naoslam.ground.GroundView.level_size`, as the laws were fitted), and a pole whose foot is in the frame
    also gets the foot-row range (:mod:`naoslam.ground`), fused with the power-law range by inverse variance, and
    the foot's bearing (exact under camera roll). ``pitch_std_rad`` is how well the pose's pitch is known; it sets
    the foot-row range's uncertainty.
    """

    def __init__(self, calibration: RangeCalibration, min_confidence: float = THESIS_CONF, range_method: str = "fused",
                 linear_bearing: bool = False, pitch_std_rad: float = math.radians(0.5),
                 maybe_confidence: float | None = None):
        if range_method not in RANGE_METHODS:
            raise ValueError(f"range method {range_method!r} is not one of {', '.join(RANGE_METHODS)}")
        if not isinstance(calibration, RangeCalibration):
            raise TypeError(f"a MeasurementModel needs a RangeCalibration, not {type(calibration).__name__} (a model "
                            "without one gives None as its calibration) - fix: `poles calibrate --model MODEL.onnx "
                            "--embed MODEL.onnx`, or pass RangeCalibration.from_dict(json.load(file)['calibration']) of a "
                            "calibration.json")
        if maybe_confidence is not None and not 0 < maybe_confidence <= min_confidence:
            raise ValueError(f"maybe_confidence {maybe_confidence} must lie above 0 and at most the operating "
                             f"threshold {min_confidence}")
        self.calibration = calibration
        self.min_confidence = min_confidence
        self.maybe_confidence = maybe_confidence
        self.range_method = range_method
        self.linear_bearing = linear_bearing
        self.pitch_std_rad = pitch_std_rad

    def measure(self, detections, image_width: int, camera_pose: CameraPose | None = None,
                image_height: int | None = None, view: GroundView | None = None) -> list[Measurement]:
        """Measurements for detections (``naoslam.perception.detections.Detection``) above the confidence threshold (and, with a
        ``maybe_confidence``, tentative ones for those between it and the threshold); a ``camera_pose`` needs the
        ``image_height`` too, or pass the frame's ground ``view`` already built. The colour filter's detections (with
        band centres) are ranged by the calibration's colour law from their band spacing."""
        if view is None and camera_pose is not None:
            if image_height is None:
                raise ValueError("a camera pose needs the image height to place the principal point")
            view = GroundView(PinholeCamera(image_width, image_height, self.calibration.hfov_deg), camera_pose)
        out = []
        lowest = self.maybe_confidence if self.maybe_confidence is not None else self.min_confidence
        for d in detections:
            if d.confidence < lowest or d.rotated_box is None:
                continue
            tentative = d.confidence < self.min_confidence
            if d.band_centres is not None:
                out.append(replace(self._colour_measurement(d, image_width), tentative=tentative))
                continue
            bearing = bearing_of_column(d.centre_column, image_width, self.calibration.hfov_deg, self.linear_bearing)
            width, height = d.rotated_box.width, d.rotated_box.height
            range_m, range_std, used = self.calibration.range_from_box(width, height, image_width,
                                                                       self.range_method, d.centre_column)
            if view is not None:
                width, height = view.level_size(width, height, range_m, bearing)
                range_m, range_std, used = self.calibration.range_from_box(width, height, image_width,
                                                                           self.range_method, d.centre_column)
            extent = d.extent if view is not None else None
            foot = view.foot_of(extent) if extent is not None else None
            if foot is not None:
                foot_std = view.foot_range_std(foot, pitch_std_rad=self.pitch_std_rad)
                fused = fuse_with_foot(range_m, range_std, foot.range_m, foot_std)
                if fused is not None:
                    (range_m, range_std), used, bearing = fused, f"{used}+foot", foot.bearing_rad
            out.append(Measurement(range_m, bearing, d.name, d.confidence, range_std,
                                   self.calibration.bearing_std_rad, used, d, tentative))
        return out

    def _colour_measurement(self, detection, image_width: int) -> Measurement:
        """The colour filter's measurement: range from the band spacing, bearing from the band-dividing column."""
        column = detection.centre_column
        range_m, range_std = self.calibration.colour_range(detection.band_distance_px, image_width, column=column)
        bearing = bearing_of_column(column, image_width, self.calibration.hfov_deg, self.linear_bearing)
        return Measurement(range_m, bearing, detection.name, detection.confidence, range_std,
                           self.calibration.bearing_std_rad, "colour filter", detection)
