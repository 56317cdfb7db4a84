"""Every back end on the same sequences: the comparison table of ``poles slam --compare`` and the demo."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from rich.table import Table

from detector.console import make_console
from detector.records import JsonRecord
from detector.slam.figures import RunFigures

from naoslam.ekf_slam import SlamConfig
from naoslam.metrics import chi2_band
from naoslam.observation import CHI2_2DOF_99
from naoslam.runner import LocalisationConfig, localisable, run_slam

#: Back ends of the comparison table: the thesis's (tables 4.1 and 4.3, raw odometry and known correspondences),
#: then the robust default and its parts switched off one at a time; last, localisation on the true map where the
#: sequence has one (simulated walks), on the same data.
BACKENDS = {
    "EKF (thesis)": SlamConfig.thesis(),
    "EKF + outlier filter (thesis)": SlamConfig.thesis(outlier_filter=True),
    "EKF + min view 3 (thesis)": SlamConfig.thesis(min_views=3),
    "FEJ-EKF (thesis)": SlamConfig.thesis(linearisation="fej"),
    "FEJ-EKF + gate + min view 3": SlamConfig.thesis(linearisation="fej", gate=CHI2_2DOF_99, min_views=3),
    "OC-EKF (thesis settings)": SlamConfig.thesis(linearisation="oc"),
    "robust default": SlamConfig(),
    "robust, standard linearisation": SlamConfig(linearisation="standard"),
    "robust, no odometry scales": SlamConfig(self_calibrate=False),
    "robust, known correspondences": SlamConfig(association="class"),
    "EKF localisation, known map": LocalisationConfig(),
    "EIF localisation, known map": LocalisationConfig(information_form=True),
    "EKF localisation, known map, no odometry scales (thesis)": LocalisationConfig(self_calibrate=False),
}


#: The last row of the comparison on simulated walks: the batch smoother of :mod:`detector.slam.reference`.
REFERENCE_ROW = "GTSAM smoother, oracle association (reference)"


@dataclass(frozen=True)
class BackendRow(JsonRecord):
    """One back end over the seeds: mean errors (m), missing and phantom landmarks in all, the median of the runs'
    mean NEES with its 95 % band, and the median mean NIS."""

    backend: str
    seeds: int
    robot_error: float | None
    landmark_error: float | None
    odometry_error: float | None
    missing: int
    phantoms: int
    nees: float | None
    nees_band95: tuple[float, float] | None
    nis: float | None


def compare_backends(make_sequence, seeds: list[int], backends: dict[str, SlamConfig | LocalisationConfig] = BACKENDS,
                     reference=None) -> list[BackendRow]:
    """Every back end on the same sequences (one per seed): mean errors, missing and phantom landmarks, NEES
    against its 95 % band over the seeds, NIS. ``reference(sequence) -> SlamResult`` adds a last row."""
    runs: dict[str, list[RunFigures]] = {name: [] for name in backends}
    if reference is not None:
        runs[REFERENCE_ROW] = []
    for seed in seeds:
        sequence = make_sequence(seed)
        for name, config in backends.items():
            if isinstance(config, SlamConfig) or localisable(sequence):
                runs[name].append(RunFigures.of(run_slam(sequence, config).metrics()))
        if reference is not None:
            runs[REFERENCE_ROW].append(RunFigures.of(reference(sequence).metrics()))
    return [_summary(name, figures) for name, figures in runs.items() if figures]


def _known(values: list[float | None]) -> list[float]:
    return [value for value in values if value is not None]


def _summary(name: str, runs: list[RunFigures]) -> BackendRow:
    def mean(values: list[float | None]) -> float | None:
        return float(np.mean(_known(values))) if _known(values) else None

    nees, nis = _known([r.nees for r in runs]), _known([r.nis for r in runs])
    return BackendRow(name, len(runs), mean([r.robot_error for r in runs]), mean([r.landmark_error for r in runs]),
                      mean([r.odometry_error for r in runs]), sum(r.missing for r in runs),
                      sum(r.phantoms for r in runs), float(np.median(nees)) if nees else None,
                      chi2_band(3, len(nees)) if nees else None, float(np.median(nis)) if nis else None)


def print_comparison(rows: list[BackendRow], title: str) -> None:
    """Print one table row per back end: errors against the truth, missing and phantom landmarks, consistency."""
    table = Table(title=title)
    for column in ("back end", "landmark mean (m)", "robot mean (m)", "odometry alone (m)", "missing", "phantoms",
                   "NEES median (3 dof)", "NEES 95 % band", "NIS median (2 dof)"):
        table.add_column(column, justify="right")
    for row in rows:
        band = row.nees_band95
        table.add_row(row.backend, *(f"{value:.3f}" if value is not None else "-"
                                     for value in (row.landmark_error, row.robot_error, row.odometry_error)),
                      str(row.missing), str(row.phantoms), f"{row.nees:.1f}" if row.nees is not None else "-",
                      f"{band[0]:.2f}-{band[1]:.2f}" if band else "-", f"{row.nis:.2f}" if row.nis is not None else "-")
    make_console().print(table)
