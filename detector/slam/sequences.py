"""What the filters are given: a simulated walk (measurement level, or its frames rendered and seen through a front
end), a UTIAS log or a recording (frames named by time stamp and an odometry CSV), and the map a localiser is told."""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from detector.console import show_progress
from detector.datasets.check import MIN_FRAME_SIDE
from detector.datasets.io import csv_rows, require_decodable
from detector.datasets.names import canonical_class
from naoslam.camera import CameraPose
from naoslam.front_end import FrontEnd
from naoslam.ground import ground_plane_problem
from naoslam.landmarks import CLASSES
from naoslam.logs import load_utias
from naoslam.measurement import RangeCalibration
from naoslam.motion import OdometryModel
from naoslam.runner import Event, Sequence, merge_frames, walk_sequence
from naoslam.sim import SimConfig, simulate


@dataclass(frozen=True)
class FrontEndSpec:
    """The front end a sequence is measured with, as a command names it: a model ``naoslam.load_detector`` opens
    (``shipped``, ``shipped-robot``, ``colour-filter``, an ONNX path) and a calibration; ``measurer`` builds it.

    ``min_confidence`` None uses the model's own operating threshold, else the thesis's 0.85. ``input_width`` runs
    a ``--dynamic`` model at that input width (None: its own). ``maybe_confidence``: detections from it up to the
    threshold go to the filter as tentative sightings (None: none).
    """

    model: str
    calibration: RangeCalibration | None = None
    min_confidence: float | None = None
    input_width: int | None = None
    maybe_confidence: float | None = None

    def measurer(self):
        """naoslam's ``FrontEnd`` for this model: a function (frame, camera_pose=None) -> measurements; with a pose,
        the ground-plane gate and the foot-row range are used (model front ends only)."""
        return FrontEnd(self.model, self.calibration, self.min_confidence, self.input_width,
                        maybe_confidence=self.maybe_confidence)


def sim_sequence(config: SimConfig, front_end: FrontEndSpec | None = None, progress: bool = True,
                 camera_pose: bool = True) -> Sequence:
    """Measurement-level walk, or image-level when a front end is given (frames rendered along the walk; with
    ``camera_pose`` the front end is told each frame's camera pose)."""
    if front_end is None:
        return walk_sequence(simulate(config))
    return image_sequences(config, [front_end], progress, camera_pose)[0]


def image_sequences(config: SimConfig, front_ends: list[FrontEndSpec], progress: bool = True,
                    camera_pose: bool = True) -> list[Sequence]:
    """One walk, its frames rendered once, seen through each front end in turn. The front ends are opened first, so
    an unreadable model or a missing calibration is refused before a minute of rendering."""
    from detector.synth.walk import render_walk, walk_camera_poses  # deferred: only image-level walks render

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


#: The odometry CSV's columns: time (s) and the odometry pose (m, m, rad).
ODOMETRY_COLUMNS = ("t", "x", "y", "theta")
#: Optional odometry CSV columns with the camera's pose (m, rad; pitch down positive) from the joint angles.
POSE_COLUMNS = ("camera_height", "camera_pitch", "camera_roll")


def recorded_sequence(frames_dir: Path, odometry_csv: Path, front_end: FrontEndSpec, time_offset_s: float,
                      camera_pose: bool = True, progress: bool = True) -> Sequence:
    """Frames named by their time stamp (``12.533.jpg``) and an odometry CSV ``t,x,y,theta``, merged in time.

    When the CSV also has ``camera_height,camera_pitch,camera_roll`` (and ``camera_pose``), each frame is measured
    with the pose of the odometry row nearest in time: ground-plane gate and foot-row range (none for a frame whose
    nearest row leaves the three camera cells empty).

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
    frames, blind = [], {reason: [] for reason in BLIND_FRAMES}
    for t, path in show_progress(sorted(stamped), f"through {Path(front_end.model).name}", "frame", enabled=progress):
        image = cv2.imread(str(path))
        reason = blind_reason(image)
        if reason:
            blind[reason].append(path)
        pose = poses[int(np.argmin(np.abs(times - t - time_offset_s)))] if poses and camera_pose else None
        frames.append(Event(t, measurements=[] if reason else measure(image, pose)))
    _report_blind_frames(frames_dir, blind, len(frames))
    events = merge_frames(controls, frames, time_offset_s)
    return Sequence(events, np.array(rows[0][1:]), OdometryModel(), {}, f"recording {Path(frames_dir).name}")


#: Why a recorded frame cannot show a front end a pole, and what to do about it.
BLIND_FRAMES = {
    "greyscale": "a pole's class is the colour of its bands, so no front end can find or name one: record the "
                 "camera's colour frames",
    f"smaller than {MIN_FRAME_SIDE} px a side": "too small to show a pole: record the camera's full frames",
}


def blind_reason(image: np.ndarray) -> str | None:
    """Which of ``BLIND_FRAMES`` a decoded recording frame is, or None when a front end can look at it."""
    if min(image.shape[:2]) < MIN_FRAME_SIDE:
        return f"smaller than {MIN_FRAME_SIDE} px a side"
    return "greyscale" if is_greyscale(image) else None


def _report_blind_frames(frames_dir: Path, blind: dict[str, list[Path]], total: int) -> None:
    """Refuse a recording whose every frame is blind; else say how many frames, and the first, for each reason that
    leaves some unseen (they stay in the recording as frames that saw nothing)."""
    found = {reason: paths for reason, paths in blind.items() if paths}
    if sum(len(paths) for paths in found.values()) == total:
        kinds = " or ".join(found)
        fixes = "; ".join(BLIND_FRAMES[reason] for reason in found)
        raise ValueError(f"{frames_dir}: every frame is {kinds} ({min(found.values(), key=len)[0].name} among them) - "
                         f"{fixes}")
    for reason, paths in found.items():
        print(f"note: {frames_dir}: {len(paths)} of {total} frames are {reason} ({paths[0].name} first) and see "
              f"no pole - {BLIND_FRAMES[reason]}")


def is_greyscale(image: np.ndarray) -> bool:
    """Whether a BGR frame holds no colour (its three channels equal, as a greyscale file decodes)."""
    return bool((image[..., 0] == image[..., 1]).all() and (image[..., 1] == image[..., 2]).all())


def _odometry_rows(odometry_csv: Path) -> tuple[list[list[float]], list[CameraPose | None] | None]:
    """The rows of an odometry CSV ``t,x,y,theta`` (checked: finite numbers, strictly increasing times) and the
    camera pose of each row when the pose columns are there (None for a row whose three camera cells are empty)."""
    rows: list[list[float]] = []
    poses: list[CameraPose | None] = []
    if not odometry_csv.is_file():
        raise ValueError(f"{odometry_csv}: no such odometry file - pass the robot's odometry as a CSV with the "
                         "header t,x,y,theta (docs/runtime.md)")
    for line, row in csv_rows(odometry_csv, ODOMETRY_COLUMNS):
        named = [name for name in POSE_COLUMNS if name in row]
        if 0 < len(named) < len(POSE_COLUMNS):
            missing = [name for name in POSE_COLUMNS if name not in row]
            raise ValueError(f"{odometry_csv}:1: {', '.join(named)} without {', '.join(missing)} - give all three "
                             "camera columns or none")
        values = _finite_cells(odometry_csv, line, row, ODOMETRY_COLUMNS)
        if rows and values[0] <= rows[-1][0]:
            raise ValueError(f"{odometry_csv}:{line}: time {values[0]:g} does not come after the previous row's "
                             f"{rows[-1][0]:g} - sort the file by t and drop repeated rows")
        rows.append(values)
        if named:
            poses.append(_camera_pose(odometry_csv, line, row))
    if len(rows) < 2:
        raise ValueError(f"{odometry_csv}: needs at least two odometry rows, found {len(rows)}")
    return rows, poses or None


def _finite_cells(path: Path, line: int, row: dict[str, str], columns: tuple[str, ...]) -> list[float]:
    """The row's ``columns`` as finite numbers, or a ValueError naming the file and line."""
    try:
        values = [float(row[name]) for name in columns]
    except (TypeError, ValueError):
        values = [math.nan]
    if not all(math.isfinite(v) for v in values):
        raise ValueError(f"{path}:{line}: not finite numbers in {','.join(columns)}")
    return values


def _camera_pose(path: Path, line: int, row: dict[str, str]) -> CameraPose | None:
    """The camera's pose on an odometry row (None where its three camera cells are empty: the joints were not read),
    refused by the file and line where it has no floor under it."""
    if not any(row.get(name) for name in POSE_COLUMNS):
        return None
    height, pitch, roll = _finite_cells(path, line, row, POSE_COLUMNS)
    pose = CameraPose(z=height, pitch=pitch, roll=roll)
    problem = ground_plane_problem(pose)
    if problem:
        raise ValueError(f"{path}:{line}: {problem} - correct the row, or leave its three camera cells empty where "
                         "the joints were not read")
    return pose


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
