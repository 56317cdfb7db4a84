"""``poles slam``: build a sequence (simulated walk, UTIAS log, or recorded frames), run back ends, report.

The runtime pieces are naoslam's; this module adds what the robot does not need: the image-level simulation
(frames rendered along the walk), plots, and the comparison table over back ends and seeds.
"""
from __future__ import annotations

import csv
import math
import textwrap
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from detector.console import show_progress
from detector.datasets.io import csv_rows, require_decodable
from detector.datasets.names import canonical_class
from naoslam.atomic import atomic_path, write_json
from naoslam.camera import CameraPose
from naoslam.ekf_slam import SlamConfig
from naoslam.landmarks import CLASSES
from naoslam.logs import load_utias
from naoslam.measurement import THESIS_CONF, Measurement, MeasurementModel, RangeCalibration
from naoslam.metrics import chi2_band
from naoslam.observation import CHI2_2DOF_99
from naoslam.runner import (Event, LocalisationConfig, Sequence, SlamResult, localisable, merge_frames, run_slam,
                            walk_sequence)
from naoslam.sim import SimConfig, simulate
from naoslam.motion import OdometryModel

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


@dataclass(frozen=True)
class FrontEnd:
    """Turns frames into measurements: an ONNX model (``shipped``: naoslam's) or the colour filter, with a calibration.

    ``min_confidence`` None uses the model's own operating threshold, else the thesis's 0.85. ``input_width`` runs
    a ``--dynamic`` model at that input width (None: its own).
    """

    model: str
    calibration: RangeCalibration | None = None
    min_confidence: float | None = None
    input_width: int | None = None

    def measurer(self):
        """A function (frame, camera_pose=None) -> measurements; with a pose, the ground-plane gate and the
        foot-row range are used (model front ends only)."""
        if self.model == "colour-filter":
            return self._colour_filter()
        from naoslam.detector import LandmarkDetector

        detector = LandmarkDetector(self.model, input_width=self.input_width)
        min_confidence = self.min_confidence if self.min_confidence is not None else detector.stored_conf or THESIS_CONF
        detector.conf = min(detector.conf, min_confidence)
        calibration = detector.check_calibration(self.calibration) if self.calibration else detector.calibration
        if calibration is None:
            raise ValueError(f"{self.model}: no calibration in the model - run `poles calibrate --embed` "
                             "or pass --calibration")
        model = MeasurementModel(calibration, min_confidence)

        def measure(frame: np.ndarray, camera_pose: CameraPose | None = None) -> list[Measurement]:
            return model.measure(detector(frame, camera_pose), frame.shape[1], camera_pose, frame.shape[0])

        return measure

    def _colour_filter(self):
        from naoslam.colour_filter import ColourFilter
        from naoslam.measurement import bearing_of_column

        calibration = self.calibration
        if calibration is None or calibration.colour_law is None:
            raise ValueError("the colour filter needs --calibration with a colour law (from `poles calibrate`)")
        colour_filter = ColourFilter()

        def measure(frame: np.ndarray, camera_pose: CameraPose | None = None) -> list[Measurement]:
            width, out = frame.shape[1], []
            for d in colour_filter(frame):
                range_m, range_std = calibration.colour_range(d.band_distance_px, width)
                out.append(Measurement(range_m, bearing_of_column(d.centre_column, width, calibration.hfov_deg),
                                       d.name, 1.0, range_std, calibration.bearing_std_rad, "colour filter"))
            return out

        return measure


def sim_sequence(config: SimConfig, front_end: FrontEnd | None = None, progress: bool = True,
                 camera_pose: bool = True) -> Sequence:
    """Measurement-level walk, or image-level when a front end is given (frames rendered along the walk; with
    ``camera_pose`` the front end is told each frame's camera pose)."""
    if front_end is None:
        return walk_sequence(simulate(config))
    return image_sequences(config, [front_end], progress, camera_pose)[0]


def image_sequences(config: SimConfig, front_ends: list[FrontEnd], progress: bool = True,
                    camera_pose: bool = True) -> list[Sequence]:
    """One walk, its frames rendered once, seen through each front end in turn. The front ends are opened first, so
    an unreadable model or a missing calibration is refused before a minute of rendering."""
    from detector.synth.walk import render_walk, walk_camera_poses

    measurers = [front_end.measurer() for front_end in front_ends]
    walk = simulate(config)
    frames = render_walk(walk, seed=config.seed, progress=progress)
    poses = walk_camera_poses(walk, config.seed) if camera_pose else [None] * len(frames)
    sequences = []
    for front_end, measure in zip(front_ends, measurers):
        seen = show_progress(zip(frames, poses), f"through {Path(front_end.model).name}", "frame", total=len(frames),
                             enabled=progress)
        sequence = walk_sequence(walk, [measure(frame, pose) for frame, pose in seen])
        sequence.name = f"{config.label}, images through {Path(front_end.model).name}"
        sequences.append(sequence)
    return sequences


#: How far a frame may lie outside the odometry's time span (the time offset can push the last frame past it).
FRAME_SLACK_S = 1.0


#: Optional odometry CSV columns with the camera's pose (m, rad; pitch down positive) from the joint angles.
POSE_COLUMNS = ("camera_height", "camera_pitch", "camera_roll")


def recorded_sequence(frames_dir: Path, odometry_csv: Path, front_end: FrontEnd, time_offset_s: float,
                      camera_pose: bool = True, progress: bool = True) -> Sequence:
    """Frames named by their time stamp (``12.533.jpg``) and an odometry CSV ``t,x,y,theta``, merged in time.

    When the CSV also has ``camera_height,camera_pitch,camera_roll`` (and ``camera_pose``), each frame is measured
    with the pose of the odometry row nearest in time: ground-plane gate and foot-row range.

    Refused with the file and line: a missing header, values that are not finite numbers, time stamps that do not
    increase, fewer than two rows, frames not named by a number or lying more than ``FRAME_SLACK_S`` outside the
    odometry's time span.
    """
    rows, poses = _odometry_rows(Path(odometry_csv))
    times = np.array([row[0] for row in rows])
    controls = [Event(b[0], OdometryModel.control(np.array(a[1:]), np.array(b[1:]))) for a, b in zip(rows, rows[1:])]
    paths = sorted(Path(frames_dir).glob("*.jpg"))
    if not paths:
        raise ValueError(f"{frames_dir}: no <time>.jpg frames")
    stamped = []
    for path in paths:
        try:
            t = float(path.stem)
        except ValueError:
            raise ValueError(f"{path}: a frame must be named by its time stamp in seconds, e.g. 12.533.jpg") from None
        if not rows[0][0] - FRAME_SLACK_S <= t + time_offset_s <= rows[-1][0] + FRAME_SLACK_S:
            raise ValueError(f"{path}: time {t + time_offset_s:g} s (with --time-offset) lies outside the odometry's "
                             f"{rows[0][0]:g}..{rows[-1][0]:g} s in {odometry_csv} - the frames and the odometry "
                             "must come from one recording on one clock")
        stamped.append((t, path))
    require_decodable([path for _, path in stamped])
    measure = front_end.measurer()
    frames = []
    for t, path in show_progress(sorted(stamped), f"through {Path(front_end.model).name}", "frame", enabled=progress):
        image = cv2.imread(str(path))
        pose = poses[int(np.argmin(np.abs(times - t - time_offset_s)))] if poses and camera_pose else None
        frames.append(Event(t, measurements=measure(image, pose)))
    events = merge_frames(controls, frames, time_offset_s)
    return Sequence(events, np.array(rows[0][1:]), OdometryModel(), {}, f"recording {Path(frames_dir).name}")


def _odometry_rows(odometry_csv: Path) -> tuple[list[list[float]], list[CameraPose] | None]:
    """The rows of an odometry CSV ``t,x,y,theta`` (checked: finite numbers, strictly increasing times) and the
    camera pose of each row when the pose columns are there."""
    rows: list[list[float]] = []
    poses: list[CameraPose] = []
    if not odometry_csv.is_file():
        raise ValueError(f"{odometry_csv}: no such odometry file - pass the robot's odometry as a CSV with the "
                         "header t,x,y,theta (README, 'The naoslam runtime')")
    for line, row in csv_rows(odometry_csv, ("t", "x", "y", "theta")):
        columns = ("t", "x", "y", "theta") + (POSE_COLUMNS if all(name in row for name in POSE_COLUMNS) else ())
        try:
            values = [float(row[k]) for k in columns]
            if not all(math.isfinite(v) for v in values):
                raise ValueError
        except (TypeError, ValueError):
            raise ValueError(f"{odometry_csv}:{line}: not finite numbers in {','.join(columns)}") from None
        if len(values) > 4:
            poses.append(CameraPose(z=values[4], pitch=values[5], roll=values[6]))
            values = values[:4]
        if rows and values[0] <= rows[-1][0]:
            raise ValueError(f"{odometry_csv}:{line}: time {values[0]:g} does not come after the previous row's "
                             f"{rows[-1][0]:g} - sort the file by t and drop repeated rows")
        rows.append(values)
    if len(rows) < 2:
        raise ValueError(f"{odometry_csv}: needs at least two odometry rows, found {len(rows)}")
    return rows, poses or None


def read_pole_map(path: Path) -> dict[str, tuple[float, float]]:
    """Where the poles stand: a CSV ``class,x,y`` (metres, the field's frame), one row per pole.

    Refused with the file and line: a class that names no landmark, a class given twice (the localiser tells poles
    apart by class), coordinates that are not finite numbers, or no rows.
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: no such map file - give a CSV with the header class,x,y (metres) and one row per "
                         "pole")
    poles: dict[str, tuple[float, float]] = {}
    for line, row in csv_rows(path, ("class", "x", "y")):
        cls = canonical_class(row["class"])
        if cls is None:
            raise ValueError(f"{path}:{line}: class {row['class']!r} names no landmark - use one of "
                             f"{' '.join(CLASSES)}")
        if cls in poles:
            raise ValueError(f"{path}:{line}: a second {cls!r} pole - the localiser tells poles apart by class, so a "
                             "map holds each class once")
        try:
            x, y = float(row["x"]), float(row["y"])
            if not (math.isfinite(x) and math.isfinite(y)):
                raise ValueError
        except ValueError:
            raise ValueError(f"{path}:{line}: x and y must be finite numbers in metres "
                             f"(got {row['x']!r}, {row['y']!r})") from None
        poles[cls] = (x, y)
    if not poles:
        raise ValueError(f"{path}: no poles - give one row class,x,y per pole")
    return poles


def utias_sequence(folder: Path, duration_s: float | None = None) -> Sequence:
    return load_utias(folder, duration_s=duration_s)


def write_outputs(result: SlamResult, sequence: Sequence, out: Path) -> dict:
    """metrics.json, path.csv, map.json (the map estimated, or a localiser's given map) and the two plots in ``out``."""
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


REFERENCE_ROW = "GTSAM smoother, oracle association (reference)"


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


#: A map's title wraps at this many characters, so the back end's long label stays inside the 7-inch figure.
MAP_TITLE_CHARS = 90


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
        ax.scatter(*estimated.T, marker="x", s=50, color="tab:red",
                   label="estimated landmarks" if result.mapped else "the map it localised on")
        for name, (x, y) in result.landmarks.items():
            ax.annotate(name, (x, y), textcoords="offset points", xytext=(4, 4), fontsize=7)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(textwrap.fill(f"{result.label} - {title}", MAP_TITLE_CHARS), fontsize=9)
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
