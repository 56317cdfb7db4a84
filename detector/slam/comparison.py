"""Every back end on the same sequences: the comparison table of ``poles slam --compare`` and the demo."""
from __future__ import annotations

import numpy as np

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


def compare_backends(make_sequence, seeds: list[int], backends: dict[str, SlamConfig | LocalisationConfig] = BACKENDS,
                     reference=None) -> list[dict]:
    """Every back end on the same sequences (one per seed): mean errors, missing and phantom landmarks, NEES
    against its 95 % band over the seeds, NIS. ``reference(sequence) -> SlamResult`` adds a last row."""
    runs: dict[str, list[dict]] = {name: [] for name in backends}
    if reference is not None:
        runs[REFERENCE_ROW] = []
    for seed in seeds:
        sequence = make_sequence(seed)
        for name, config in backends.items():
            if isinstance(config, SlamConfig) or localisable(sequence):
                runs[name].append(run_slam(sequence, config).metrics())
        if reference is not None:
            runs[REFERENCE_ROW].append(reference(sequence).metrics())
    return [_summary(name, metrics) for name, metrics in runs.items() if metrics]


def _summary(name: str, runs: list[dict]) -> dict:
    row: dict = {"backend": name, "seeds": len(runs)}
    for key in ("robot_error", "landmark_error", "odometry_error"):
        values = [r[key]["mean"] for r in runs if key in r]
        if values:
            row[key] = float(np.mean(values))
    row["missing"] = sum(len(r.get("landmarks_missing", [])) for r in runs)
    row["phantoms"] = sum(len(r.get("phantoms", {})) for r in runs)
    nees = [r["nees"]["mean"] for r in runs if "nees" in r]
    if nees:
        row["nees"] = float(np.median(nees))
        row["nees_band95"] = chi2_band(3, len(nees))
    nis = [r["nis"]["mean"] for r in runs if "nis" in r]
    if nis:
        row["nis"] = float(np.median(nis))
    return row


def print_comparison(rows: list[dict], title: str) -> None:
    """Print one table row per back end: errors against the truth, missing and phantom landmarks, consistency."""
    from detector.console import make_console
    from rich.table import Table

    table = Table(title=title)
    for column in ("back end", "landmark mean (m)", "robot mean (m)", "odometry alone (m)", "missing", "phantoms",
                   "NEES median (3 dof)", "NEES 95 % band", "NIS median (2 dof)"):
        table.add_column(column, justify="right")
    for row in rows:
        band = row.get("nees_band95")
        table.add_row(row["backend"], *(f"{row[k]:.3f}" if k in row else "-"
                                        for k in ("landmark_error", "robot_error", "odometry_error")),
                      str(row["missing"]), str(row["phantoms"]),
                      f"{row['nees']:.1f}" if "nees" in row else "-",
                      f"{band[0]:.2f}-{band[1]:.2f}" if band else "-",
                      f"{row['nis']:.2f}" if "nis" in row else "-")
    make_console().print(table)
