"""``poles slam``: build a sequence (simulated walk, UTIAS log, or recorded frames), run back ends, report.

The runtime pieces are naoslam's; this module adds what the robot does not need: the image-level simulation
(frames rendered along the walk), plots, and the comparison table over back ends and seeds.
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from naoslam.atomic import atomic_path, write_json
from naoslam.ekf_slam import SlamConfig
from naoslam.logs import load_utias
from naoslam.measurement import THESIS_CONF, Measurement, MeasurementModel, RangeCalibration
from naoslam.observation import CHI2_2DOF_99
from naoslam.runner import Event, Sequence, SlamResult, merge_frames, run_slam, walk_sequence
from naoslam.sim import SimConfig, simulate
from naoslam.motion import OdometryModel

#: Back ends of the comparison table (thesis tables 4.1 and 4.3, plus the gate).
BACKENDS = {
    "EKF": SlamConfig(),
    "EKF + outlier filter": SlamConfig(outlier_filter=True),
    "EKF + gate": SlamConfig(gate=CHI2_2DOF_99),
    "EKF + min view 3": SlamConfig(min_views=3),
    "EKF + min view 5": SlamConfig(min_views=5),
    "FEJ-EKF": SlamConfig(fej=True),
    "FEJ-EKF + min view 5": SlamConfig(fej=True, min_views=5),
    "FEJ-EKF + gate + min view 3": SlamConfig(fej=True, gate=CHI2_2DOF_99, min_views=3),
}


@dataclass(frozen=True)
class FrontEnd:
    """Turns frames into measurements: an ONNX model (``shipped``: naoslam's) or the colour filter, with a calibration.

    ``min_confidence`` None uses the model's own operating threshold, else the thesis's 0.85.
    """

    model: str
    calibration: RangeCalibration | None = None
    min_confidence: float | None = None

    def measurer(self):
        """A function frame -> measurements."""
        if self.model == "colour-filter":
            return self._colour_filter()
        from naoslam.detector import LandmarkDetector

        detector = LandmarkDetector(self.model)
        min_confidence = self.min_confidence if self.min_confidence is not None else detector.stored_conf or THESIS_CONF
        detector.conf = min(detector.conf, min_confidence)
        calibration = self.calibration or detector.calibration
        if calibration is None:
            raise ValueError(f"{self.model}: no calibration in the model - run `poles calibrate --embed` "
                             "or pass --calibration")
        model = MeasurementModel(calibration, min_confidence)
        return lambda frame: model.measure(detector(frame), frame.shape[1])

    def _colour_filter(self):
        from naoslam.colour_filter import ColourFilter
        from naoslam.measurement import bearing_of_column

        calibration = self.calibration
        if calibration is None or calibration.colour_law is None:
            raise ValueError("the colour filter needs --calibration with a colour law (from `poles calibrate`)")
        colour_filter = ColourFilter()

        def measure(frame: np.ndarray) -> list[Measurement]:
            width, out = frame.shape[1], []
            for d in colour_filter(frame):
                range_m, range_std = calibration.colour_range(d.band_distance_px, width)
                out.append(Measurement(range_m, bearing_of_column(d.centre_column, width, calibration.hfov_deg),
                                       d.name, 1.0, range_std, calibration.bearing_std_rad, "colour filter"))
            return out

        return measure


def sim_sequence(config: SimConfig, front_end: FrontEnd | None = None, progress: bool = True) -> Sequence:
    """Measurement-level walk, or image-level when a front end is given (frames rendered along the walk)."""
    if front_end is None:
        return walk_sequence(simulate(config))
    return image_sequences(config, [front_end], progress)[0]


def image_sequences(config: SimConfig, front_ends: list[FrontEnd], progress: bool = True) -> list[Sequence]:
    """One walk, its frames rendered once, seen through each front end in turn."""
    from detector.synth.walk import render_walk

    walk = simulate(config)
    frames = render_walk(walk, seed=config.seed, progress=progress)
    sequences = []
    for front_end in front_ends:
        measure = front_end.measurer()
        sequence = walk_sequence(walk, [measure(frame) for frame in frames])
        sequence.name = f"sim {config.path}, images through {Path(front_end.model).name}"
        sequences.append(sequence)
    return sequences


def recorded_sequence(frames_dir: Path, odometry_csv: Path, front_end: FrontEnd, time_offset_s: float) -> Sequence:
    """Frames named by their time stamp (``12.533.jpg``) and an odometry CSV ``t,x,y,theta``, merged in time."""
    rows = []
    with Path(odometry_csv).open(newline="", encoding="utf-8-sig", errors="replace") as handle:
        reader = csv.DictReader(handle)
        if not reader.fieldnames or not {"t", "x", "y", "theta"} <= set(reader.fieldnames):
            raise ValueError(f"{odometry_csv}:1: header must be t,x,y,theta (got {reader.fieldnames})")
        for line, row in enumerate(reader, start=2):
            try:
                values = [float(row[k]) for k in ("t", "x", "y", "theta")]
                if not all(math.isfinite(v) for v in values):
                    raise ValueError
                rows.append(values)
            except (TypeError, ValueError):
                raise ValueError(f"{odometry_csv}:{line}: not finite numbers in t,x,y,theta") from None
    if len(rows) < 2:
        raise ValueError(f"{odometry_csv}: needs at least two odometry rows")
    rows.sort()
    controls = [Event(b[0], OdometryModel.control(np.array(a[1:]), np.array(b[1:]))) for a, b in zip(rows, rows[1:])]
    measure = front_end.measurer()
    frames = []
    for path in sorted(Path(frames_dir).glob("*.jpg"), key=lambda p: float(p.stem)):
        image = cv2.imread(str(path))
        if image is None:
            raise ValueError(f"{path}: cannot be decoded as an image")
        frames.append(Event(float(path.stem), measurements=measure(image)))
    if not frames:
        raise ValueError(f"{frames_dir}: no <time>.jpg frames")
    events = merge_frames(controls, frames, time_offset_s)
    return Sequence(events, np.array(rows[0][1:]), OdometryModel(), {}, f"recording {Path(frames_dir).name}")


def utias_sequence(folder: Path, duration_s: float | None = None) -> Sequence:
    return load_utias(folder, duration_s=duration_s)


def write_outputs(result: SlamResult, sequence: Sequence, out: Path) -> dict:
    """metrics.json, path.csv, map.json and the two plots in ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    metrics = {"sequence": sequence.name, **result.metrics()}
    write_json(out / "metrics.json", metrics)
    write_json(out / "map.json", {k: [float(v[0]), float(v[1])] for k, v in result.landmarks.items()})
    with atomic_path(out / "path.csv") as tmp:
        with tmp.open("w", newline="") as handle:
            writer = csv.writer(handle)
            writer.writerow(["t", "x", "y", "theta"] + (["true_x", "true_y", "true_theta"]
                                                        if result.true_poses is not None else []))
            for i, t in enumerate(result.times):
                extra = list(result.true_poses[i]) if result.true_poses is not None else []
                writer.writerow([f"{t:.3f}", *(f"{v:.4f}" for v in result.poses[i]), *(f"{v:.4f}" for v in extra)])
    plot_map(result, out / "map.png", sequence.name)
    if result.true_poses is not None:
        plot_errors(result, out / "errors.png")
    return metrics


def compare_backends(make_sequence, seeds: list[int], backends: dict[str, SlamConfig] = BACKENDS) -> list[dict]:
    """Every back end on the same sequences (one per seed); mean robot and landmark errors over seeds."""
    sums: dict[str, list[dict]] = {name: [] for name in backends}
    for seed in seeds:
        sequence = make_sequence(seed)
        for name, config in backends.items():
            sums[name].append(run_slam(sequence, config).metrics())
    rows = []
    for name, runs in sums.items():
        row = {"backend": name, "seeds": len(runs)}
        for key in ("robot_error", "landmark_error", "odometry_error"):
            values = [r[key]["mean"] for r in runs if key in r]
            if values:
                row[key] = float(np.mean(values))
        nees = [r["nees"]["mean"] for r in runs if "nees" in r]
        if nees:
            row["nees"] = float(np.median(nees))
        rows.append(row)
    return rows


def print_comparison(rows: list[dict], title: str) -> None:
    from rich.console import Console
    from rich.table import Table

    table = Table(title=title)
    for column in ("back end", "landmark mean (m)", "robot mean (m)", "odometry alone (m)", "NEES (median, 3 dof)"):
        table.add_column(column, justify="right")
    for row in rows:
        table.add_row(row["backend"], *(f"{row[k]:.4f}" if k in row else "-"
                                        for k in ("landmark_error", "robot_error", "odometry_error")),
                      f"{row['nees']:.1f}" if "nees" in row else "-")
    Console().print(table)


def plot_map(result: SlamResult, png: Path, title: str) -> Path:
    """True and estimated landmarks and paths (and odometry), like the thesis's map figures."""
    from detector.figures import plt, save_figure

    fig, ax = plt.subplots(figsize=(7, 5), constrained_layout=True)
    if result.true_poses is not None:
        ax.plot(result.true_poses[:, 0], result.true_poses[:, 1], color="black", linewidth=1, label="true path")
    if result.odometry_poses is not None:
        ax.plot(result.odometry_poses[:, 0], result.odometry_poses[:, 1], color="grey", linestyle=":",
                label="odometry")
    ax.plot(result.poses[:, 0], result.poses[:, 1], color="tab:blue", linewidth=1, label="estimated path")
    truth = result.landmarks_truth
    if truth:
        ax.scatter(*np.array(list(truth.values())).T, marker="s", s=50, facecolors="none", edgecolors="black",
                   label="true landmarks")
    if result.landmarks:
        estimated = np.array(list(result.landmarks.values()))
        ax.scatter(*estimated.T, marker="x", s=50, color="tab:red", label="estimated landmarks")
        for name, (x, y) in result.landmarks.items():
            ax.annotate(name, (x, y), textcoords="offset points", xytext=(4, 4), fontsize=7)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(f"{result.label} - {title}", fontsize=9)
    ax.legend(fontsize=7, loc="best")
    ax.grid(alpha=0.3)
    return save_figure(fig, png)


def plot_errors(result: SlamResult, png: Path) -> Path:
    """Robot position error over time for the filter and for odometry alone."""
    from detector.figures import plt, save_figure

    fig, ax = plt.subplots(figsize=(7, 3), constrained_layout=True)
    ax.plot(result.times, np.linalg.norm(result.poses[:, :2] - result.true_poses[:, :2], axis=1), label=result.label)
    if result.odometry_poses is not None:
        ax.plot(result.times, np.linalg.norm(result.odometry_poses[:, :2] - result.true_poses[:, :2], axis=1),
                color="grey", linestyle=":", label="odometry alone")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("robot position error (m)")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    return save_figure(fig, png)
