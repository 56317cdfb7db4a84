"""Real logs: the UTIAS MRCLAM format (velocity odometry, range-bearing by barcode, landmark truth) and
OptiTrack (Motive) CSV exports as ground truth for Nao recordings."""
from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from naoslam.measurement import Measurement
from naoslam.motion import VelocityModel
from naoslam.runner import Event, Sequence, merge_frames

UTIAS_FILES = ("Odometry.dat", "Measurement.dat", "Barcodes.dat", "Landmark_Groundtruth.dat")


def _table(path: Path, columns: int) -> np.ndarray:
    """Rows of a whitespace-separated .dat file, '#' lines skipped; errors name the file and line."""
    rows = []
    try:
        text_lines = path.read_text(encoding="utf-8").splitlines()
    except UnicodeDecodeError:
        raise ValueError(f"{path}: not a text file - give the MRCLAM .dat files as downloaded") from None
    for number, line in enumerate(text_lines, start=1):
        text = line.strip()
        if not text or text.startswith("#"):
            continue
        parts = text.split()
        try:
            values = [float(v) for v in parts[:columns]]
        except ValueError:
            raise ValueError(f"{path}:{number}: {text[:60]!r} is not {columns} numbers") from None
        if len(parts) < columns:
            raise ValueError(f"{path}:{number}: expected {columns} columns, found {len(parts)}")
        if not all(math.isfinite(v) for v in values):
            raise ValueError(f"{path}:{number}: {text[:60]!r} holds nan or inf - repair or delete the line")
        rows.append(values)
    return np.array(rows).reshape(-1, columns)


def _require_time_order(path: Path, times: np.ndarray) -> None:
    """Odometry must run forward in time: a stamp out of order would feed the filter a negative time step."""
    if len(times) < 2:
        raise ValueError(f"{path}: needs at least two odometry rows, found {len(times)}")
    backwards = np.flatnonzero(np.diff(times) < 0)
    if backwards.size:
        raise ValueError(f"{path}: time stamp {times[backwards[0] + 1]} comes after {times[backwards[0]]} (row "
                         f"{backwards[0] + 2} of the data) - sort the file by time")


def load_utias(folder: Path, range_std: float = 0.1, bearing_std: float = math.radians(3.0),
               duration_s: float | None = None) -> Sequence:
    """One robot's UTIAS MRCLAM log as a sequence: velocity controls between odometry stamps, frames of
    landmark measurements (measurements of other robots' barcodes are left out). No robot truth is needed:
    the map is scored after a rigid alignment to the landmark ground truth."""
    if duration_s is not None and not (math.isfinite(duration_s) and duration_s > 0):
        raise ValueError(f"duration_s {duration_s:g} must be a positive number of seconds (None: the whole log)")
    folder = Path(folder)
    missing = [name for name in UTIAS_FILES if not (folder / name).is_file()]
    if missing:
        logs_inside = sorted(sub.name for sub in folder.glob("*/") if all((sub / n).is_file() for n in UTIAS_FILES))
        fix = f" - pass the folder of one log: {', '.join(logs_inside)}" if logs_inside else ""
        raise FileNotFoundError(f"{folder}: not a UTIAS MRCLAM folder, missing {', '.join(missing)}{fix}")
    odometry = _table(folder / "Odometry.dat", 3)
    _require_time_order(folder / "Odometry.dat", odometry[:, 0])
    measurements = _table(folder / "Measurement.dat", 4)
    barcodes = _table(folder / "Barcodes.dat", 2)
    truth = _table(folder / "Landmark_Groundtruth.dat", 3)
    for name, rows in (("Measurement.dat", measurements), ("Barcodes.dat", barcodes),
                       ("Landmark_Groundtruth.dat", truth)):
        if len(rows) == 0:
            raise ValueError(f"{folder / name}: no rows, only comments - give the log's {name} as downloaded")
    subject_of_barcode = {int(b): int(s) for s, b in barcodes}
    landmarks = {str(int(s)): (x, y) for s, x, y in truth}
    start = odometry[0, 0]
    end = math.inf if duration_s is None else start + duration_s
    controls = [Event(t, np.array([v, w, t_next - t]))
                for (t, v, w), t_next in zip(odometry[:-1], odometry[1:, 0]) if t < end]
    frames: dict[float, list[Measurement]] = {}
    for t, barcode, r, b in measurements:
        subject = str(subject_of_barcode.get(int(barcode), -1))
        if subject in landmarks and t < end:
            frames.setdefault(t, []).append(Measurement(r, b, subject, 1.0, range_std, bearing_std, "utias"))
    events = merge_frames(controls, [Event(t, measurements=m) for t, m in sorted(frames.items())])
    for event in events:
        event.t -= start
    return Sequence(events, np.zeros(3), VelocityModel(), landmarks, f"UTIAS {folder.name}")


def load_optitrack(path: Path, body: str | None = None) -> np.ndarray:
    """Planar ground truth (t, x, y, yaw) of one rigid body from a Motive CSV export (Y up: x = X, y = -Z)."""
    path = Path(path)
    with path.open(newline="") as handle:
        rows = list(csv.reader(handle))
    header = next((i for i, row in enumerate(rows) if row[:2] and row[1].startswith("Time")), None)
    if header is None or header < 3:
        raise ValueError(f"{path}: no 'Frame,Time (Seconds),...' header - export the take from Motive as CSV")
    names, kinds, fields = rows[header - 3], rows[header - 1], rows[header]
    wanted = body or next(n for n in names[2:] if n)
    columns = {(kind, field): i for i, (name, kind, field) in enumerate(zip(names, kinds, fields))
               if name == wanted}
    try:
        qx, qy, qz, qw = (columns[("Rotation", k)] for k in "XYZW")
        px, pz = columns[("Position", "X")], columns[("Position", "Z")]
    except KeyError:
        raise ValueError(f"{path}: rigid body {wanted!r} has no quaternion rotation and position columns") from None
    out = []
    for number, row in enumerate(rows[header + 1:], start=header + 2):
        if len(row) <= max(qx, qy, qz, qw, px, pz) or not row[px]:
            continue  # untracked frame
        try:
            x, y, z, w = (float(row[i]) for i in (qx, qy, qz, qw))
            yaw = math.atan2(2 * (w * y + x * z), 1 - 2 * (y * y + x * x))  # rotation about the vertical (Y) axis
            out.append([float(row[1]), float(row[px]), -float(row[pz]), yaw])
        except ValueError:
            raise ValueError(f"{path}:{number}: not numbers in the {wanted!r} columns") from None
    return np.array(out).reshape(-1, 4)
