"""What a range calibration reports beside the laws it fits: each fit's quality, the noise a walk measured, the
bearing error and the range error by distance (the ``report`` of calibration.json)."""
from __future__ import annotations

from dataclasses import dataclass, replace

from detector.records import JsonRecord


@dataclass(frozen=True)
class MeanFit(JsonRecord):
    """The thesis-style fit through the mean pixel size at each distinct range: range = a * px^b."""

    a: float
    b: float


@dataclass(frozen=True)
class WalkNoise(JsonRecord):
    """A law's relative range error on a walk's sightings: its robust spread (what the filter is told, at least)
    and its median (the law's bias on the walk)."""

    sightings: int
    relative_std: float
    median_log_error: float


@dataclass(frozen=True)
class LawReport(JsonRecord):
    """One fitted law, range = a * px^b, with its residual spread, R^2 in log space and the poles it was fitted on."""

    a: float
    b: float
    relative_std: float
    r2: float
    samples: int
    per_distance_mean_fit: MeanFit | None
    #: The noise measured on a walk (``--noise-data``), if one was given and showed enough sightings.
    walk: WalkNoise | None = None
    #: Sightings of a walk too few to measure an optional law's noise (it keeps the default).
    walk_too_few: int | None = None


@dataclass(frozen=True)
class BearingError(JsonRecord):
    """The pinhole bearing of the mask centre against the true bearing, in degrees."""

    mean: float
    std: float
    max_abs: float


@dataclass(frozen=True)
class RangeErrors(JsonRecord):
    """Mean absolute relative range error (%) of a group of poles for each way of choosing the range: the width law,
    the height law, the thesis's rule, the fused estimate; the foot-row range over the poles with one, and the fused
    range with it (as the robot measures with a camera pose)."""

    #: The group: a range bin ("1.25-2.00", m) or "cut by the border".
    label: str
    samples: int
    width: float
    height: float
    rule: float
    fused: float
    foot_samples: int = 0
    foot: float | None = None
    fused_foot: float | None = None


@dataclass(frozen=True)
class CalibrationReport(JsonRecord):
    """How the calibration was fitted and how well it ranges the poles it was fitted on."""

    samples: int
    reference_width_px: int
    width: LawReport
    height: LawReport
    colour: LawReport | None
    upright_ratio: float
    bearing_error_deg: BearingError | None
    errors_by_range: tuple[RangeErrors, ...]
    errors_cut_by_border: RangeErrors | None
    #: What was measured (label masks, a model's masks or boxes) and where the walk noise came from.
    source: str = ""
    noise_source: str = ""

    def laws(self) -> dict[str, LawReport]:
        """The fitted laws by name: width, height and colour where there is one."""
        return {name: law for name, law in (("width", self.width), ("height", self.height),
                                            ("colour", self.colour)) if law is not None}

    def with_sources(self, source: str, noise_source: str) -> CalibrationReport:
        return replace(self, source=source, noise_source=noise_source)
