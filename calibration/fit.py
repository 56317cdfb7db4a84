"""Power-law fits ``range = a * px^b`` (least squares in log-log space) and the calibration they make."""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np

from calibration.report import BearingError, CalibrationReport, LawReport, MeanFit, RangeErrors, WalkNoise
from calibration.samples import SizeSample, as_arrays, measures_law
from naoslam.camera import NAO_HFOV_DEG
from naoslam.landmarks import PoleGeometry
from naoslam.measurement import PowerLaw, RangeCalibration, bearing_of_column, fuse_with_foot

#: Distance bins (m) of the per-distance report.
RANGE_BINS = (0.0, 0.75, 1.25, 2.0, 3.0, 4.0, 6.0, 9.5)
#: The least relative range noise each law is given, whatever its fit's residuals, unless ``--noise-data`` measures
#: it: still calibration shots show less than a walking robot's frames do (sway blurs and widens a mask), and a
#: filter told less than a walk shows is over-confident and maps a pole twice. The floors are the spread the shipped
#: model's masks (and the colour filter's band distances) show on nine rendered walks; docs/range-calibration.md
#: gives the measurements.
WALK_RELATIVE_STD = {"width": 0.13, "height": 0.020, "colour": 0.028}
#: Fewest sightings of a walk that measure a law's noise (``--noise-data``).
MIN_NOISE_SIGHTINGS = 20


@dataclass(frozen=True)
class LawFit:
    """A fitted law with its goodness of fit (R^2 in log space) and the thesis-style fit through per-range means."""

    law: PowerLaw
    r2: float
    samples: int
    per_distance: PowerLaw | None

    def report(self, walk: WalkNoise | None = None, walk_too_few: int | None = None) -> LawReport:
        """The fit as reported, with what a walk's sightings measured of its noise."""
        mean_fit = MeanFit(self.per_distance.a, self.per_distance.b) if self.per_distance else None
        return LawReport(self.law.a, self.law.b, self.law.relative_std, self.r2, self.samples, mean_fit, walk,
                         walk_too_few)


def fit_power_law(px: np.ndarray, range_m: np.ndarray) -> tuple[PowerLaw, float]:
    """Least squares of log(range) on log(px); returns the law (with residual std) and R^2."""
    px, range_m = np.asarray(px, float), np.asarray(range_m, float)
    keep = (px > 0) & (range_m > 0)
    if keep.sum() < 2 or len(np.unique(np.round(range_m[keep], 3))) < 2:
        raise ValueError("a power law needs poles at two or more different ranges")
    x, y = np.log(px[keep]), np.log(range_m[keep])
    b, log_a = np.polyfit(x, y, 1)
    residual = y - (log_a + b * x)
    r2 = 1 - residual.var() / y.var() if y.var() > 0 else 1.0
    std = float(np.sqrt(np.sum(residual ** 2) / max(len(x) - 2, 1)))
    return PowerLaw(float(math.exp(log_a)), float(b), std), float(r2)


def fit_law(px: np.ndarray, range_m: np.ndarray) -> LawFit:
    """All-points fit, plus the thesis's fit through the mean pixel size at each distinct range."""
    law, r2 = fit_power_law(px, range_m)
    ranges = np.round(range_m, 3)
    distinct = np.unique(ranges)
    per_distance = None
    if len(distinct) >= 2:
        per_distance = fit_power_law(np.array([px[ranges == r].mean() for r in distinct]), distinct)[0]
    return LawFit(law, r2, len(px), per_distance)


def calibrate(samples: list[SizeSample], geometry: PoleGeometry = PoleGeometry(), hfov_deg: float = NAO_HFOV_DEG,
              walk_samples: list[SizeSample] | None = None) -> tuple[RangeCalibration, CalibrationReport]:
    """Fit the width and height laws on on-axis sizes (height only on whole poles), the colour law and the bearing
    noise. Each law's noise is at least a walking robot's: measured on ``walk_samples`` (sightings in a walk's
    frames) when given, else ``WALK_RELATIVE_STD``."""
    reference_width = samples[0].image_width
    columns = as_arrays(samples, reference_width, hfov_deg, geometry)
    whole = ~columns["partial"]
    if len(np.unique(np.round(columns["range"][whole], 3))) < 2:  # too few whole poles: use every pole
        whole = np.ones_like(whole)
    width_fit = fit_law(columns["width"], columns["range"])
    height_fit = fit_law(columns["height"][whole], columns["range"][whole])
    upright_ratio = float(np.median(columns["width"][whole] / columns["height"][whole]))
    bearing_std, bearing_error = _bearing_std(samples, hfov_deg)
    walk = None if walk_samples is None else as_arrays(walk_samples, reference_width, hfov_deg, geometry)
    width_law, width_report = _walk_noise(width_fit, "width", walk)
    height_law, height_report = _walk_noise(height_fit, "height", walk)
    colour_fit = _colour_fit(columns)
    colour_law, colour_report = (None, None) if colour_fit is None else \
        _walk_noise(colour_fit, "colour", walk, required=False)
    calibration = RangeCalibration(width_law, height_law, reference_width, upright_ratio, bearing_std_rad=bearing_std,
                                   hfov_deg=hfov_deg, colour_law=colour_law, off_axis_corrected=True,
                                   colour_off_axis_corrected=True)
    cut = [s for s in samples if s.partial]
    report = CalibrationReport(len(samples), reference_width, width_report, height_report, colour_report,
                               upright_ratio, bearing_error, tuple(range_errors(samples, calibration)),
                               method_errors(cut, calibration, "cut by the border") if cut else None)
    return calibration, report


def _walk_noise(fit: LawFit, size: Literal["width", "height", "colour"], walk: dict[str, np.ndarray] | None,
                required: bool = True) -> tuple[PowerLaw, LawReport]:
    """The fitted law with its relative s.d. raised to at least a walking robot's: the law's spread on the walk's
    sightings (heights of whole poles only), or ``WALK_RELATIVE_STD`` without them; and the fit's report. A walk with
    too few sightings is refused where the law is ``required``; otherwise (the colour filter, a baseline) it keeps
    the default."""
    law = fit.law
    keep = None if walk is None else measures_law(walk, size)
    if keep is None or (not required and keep.sum() < MIN_NOISE_SIGHTINGS):
        floor = WALK_RELATIVE_STD[size]
        report = fit.report(walk_too_few=None if keep is None else int(keep.sum()))
    else:
        if keep.sum() < MIN_NOISE_SIGHTINGS:
            raise ValueError(f"--noise-data: {int(keep.sum())} sightings measure the {size} law, at least "
                             f"{MIN_NOISE_SIGHTINGS} needed - add frames of the walk (whole poles for the height law)")
        errors = relative_log_errors(law, walk[size][keep], walk["range"][keep])
        floor = robust_spread(errors)
        report = fit.report(WalkNoise(int(keep.sum()), floor, float(np.median(errors))))
    return replace(law, relative_std=max(law.relative_std, floor)), report


def relative_log_errors(law: PowerLaw, px: np.ndarray, range_m: np.ndarray) -> np.ndarray:
    """log(range the law gives / true range) for each sighting: its relative range error."""
    return np.log(law(np.asarray(px, float)) / np.asarray(range_m, float))


def robust_spread(errors: np.ndarray) -> float:
    """The s.d. of a normal error with the same median absolute size, 1.4826 x median |error|: bias included (an
    error about the truth, not the mean), and not moved by the few wild sightings a filter's gate drops."""
    return float(1.4826 * np.median(np.abs(errors)))


def _colour_fit(columns: dict[str, np.ndarray]) -> LawFit | None:
    """The colour filter's law: range from its own pixels per cm between the two band centres, on the poles it
    found (None when it found too few at two ranges)."""
    found = measures_law(columns, "colour")
    if len(np.unique(np.round(columns["range"][found], 3))) < 2:
        return None
    return fit_law(columns["colour"][found], columns["range"][found])


def _bearing_std(samples: list[SizeSample], hfov_deg: float) -> tuple[float, BearingError | None]:
    """Standard deviation of the pinhole bearing of the mask centre against the true bearing (1 deg if unknown),
    and the errors it was measured from."""
    known = [s for s in samples if s.bearing_rad is not None and s.centre_column is not None]
    if len(known) < 2:
        return math.radians(1.0), None
    errors = np.array([bearing_of_column(s.centre_column, s.image_width, hfov_deg) - s.bearing_rad for s in known])
    measured = BearingError(float(np.degrees(errors.mean())), float(np.degrees(errors.std(ddof=1))),
                            float(np.degrees(np.abs(errors).max())))
    return float(max(np.sqrt(np.mean(errors ** 2)), math.radians(0.1))), measured


def range_errors(samples: list[SizeSample], calibration: RangeCalibration) -> list[RangeErrors]:
    """Mean absolute relative range error (%) per distance bin for each way of choosing the range (see
    :func:`method_errors`)."""
    rows = []
    for low, high in zip(RANGE_BINS[:-1], RANGE_BINS[1:]):
        chosen = [s for s in samples if low <= s.range_m < high]
        if chosen:
            rows.append(method_errors(chosen, calibration, f"{low:.2f}-{high:.2f}"))
    return rows


def method_errors(chosen: list[SizeSample], calibration: RangeCalibration, label: str = "") -> RangeErrors:
    """Mean absolute relative range error (%) of ``chosen`` for each way of choosing the range. ``foot``: over the
    poles with a foot-row range (camera pose known, foot in the frame); ``fused_foot``: over all, as
    ``MeasurementModel`` measures with a pose (the fused box range where there is no foot or it disagrees)."""
    by_method = {}
    for method in ("width", "height", "rule", "fused"):
        ranges = [calibration.range_from_box(s.width_px, s.height_px, s.image_width, method, s.centre_column)[0]
                  for s in chosen]
        by_method[method] = 100 * float(np.mean([abs(r - s.range_m) / s.range_m for r, s in zip(ranges, chosen)]))
    with_foot = [s for s in chosen if s.foot_range_m is not None]
    foot = fused_foot = None
    if with_foot:
        foot = 100 * float(np.mean([abs(s.foot_range_m - s.range_m) / s.range_m for s in with_foot]))
        fused_foot = 100 * float(np.mean([abs(_with_foot(s, calibration) - s.range_m) / s.range_m for s in chosen]))
    return RangeErrors(label, len(chosen), **by_method, foot_samples=len(with_foot), foot=foot, fused_foot=fused_foot)


def _with_foot(sample: SizeSample, calibration: RangeCalibration) -> float:
    """The range ``MeasurementModel`` gives with a camera pose: the fused box range and the foot-row range combined,
    the box range alone where they disagree."""
    box_range, box_std, _ = calibration.range_from_box(sample.width_px, sample.height_px, sample.image_width, "fused",
                                                       sample.centre_column)
    if sample.foot_range_m is None:
        return box_range
    fused = fuse_with_foot(box_range, box_std, sample.foot_range_m, sample.foot_range_std)
    return box_range if fused is None else fused[0]
