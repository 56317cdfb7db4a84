"""Parse YOLO segmentation label files line by line, reporting every problem with its line number."""
from __future__ import annotations

import math
from collections import Counter
from pathlib import Path

import numpy as np

from detector.datasets.model import Instance, Problem
from detector.datasets.polygons import polygon_area

#: Coordinates may stray this far outside [0, 1] (annotation tools round); they are clipped when read.
COORD_TOLERANCE = 0.01
#: The words every command uses for detection (box-only) labels, which segmentation training cannot use.
BOX_ONLY = "segmentation labels needed: export as instance segmentation"
#: A polygon smaller than this (in normalised units, about 0.03 px^2 at 640x480) has no area.
MIN_NORMALISED_AREA = 1e-7


def parse_label_file(path: Path, names: tuple[str | None, ...],
                     unknown_uses: Counter | None = None) -> tuple[list[Instance], list[Problem]]:
    """Read ``class x1 y1 x2 y2 ...`` lines; ``names[i]`` is the canonical code of class id i (None if unknown).

    Lines with errors are left out of the returned instances and reported instead; ``unknown_uses``, where given,
    counts the lines of each class id that names no landmark or lies beyond ``names``.
    """
    instances: list[Instance] = []
    problems: list[Problem] = []
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        fix = (f"let your user read it (chmod u+r {path})" if isinstance(exc, PermissionError)
               else "replace it with a UTF-8 text file")
        return [], [Problem("error", path, None, f"cannot read label file ({exc})", fix)]
    for number, raw in enumerate(text.splitlines(), start=1):
        if not raw.strip():
            continue
        instance, found = _parse_line(path, number, raw.split(), names, unknown_uses)
        problems += found
        if instance is not None:
            instances.append(instance)
    return instances, problems


def _parse_line(path: Path, number: int, tokens: list[str], names: tuple[str | None, ...],
                unknown_uses: Counter | None):
    def error(message: str, fix: str) -> tuple[None, list[Problem]]:
        return None, [Problem("error", path, number, message, fix)]

    try:
        values = [float(t) for t in tokens]
    except ValueError:
        return error(f"not a number in {' '.join(tokens)[:60]!r}", "each line is `class x1 y1 x2 y2 ...` in numbers")
    class_value, coords = values[0], np.array(values[1:], np.float64)
    if len(coords) == 4:
        return error(f"4 numbers after the class: a bounding box (or a 2-point outline), not a polygon - {BOX_ONLY}",
                     "export the dataset from Roboflow as YOLOv8 *instance segmentation* (polygons)")
    if not math.isfinite(class_value) or class_value != int(class_value) or not 0 <= class_value < len(names):
        if unknown_uses is not None and math.isfinite(class_value) and class_value == int(class_value) >= len(names):
            unknown_uses[int(class_value)] += 1
        return error(f"class id {tokens[0]} out of range 0..{len(names) - 1}",
                     "use an index into `names` in data.yaml, or add the class there")
    cls = names[int(class_value)]
    if cls is None:
        if unknown_uses is not None:
            unknown_uses[int(class_value)] += 1
        return error(f"class id {int(class_value)} names no landmark", f"read class {int(class_value)} as a pole with "
                     "`--rename` (data.yaml's message for it says how), or delete this line")
    if len(coords) % 2:
        return error(f"odd number of coordinates ({len(coords)})", "each vertex needs an x and a y")
    if len(coords) < 6:
        return error(f"only {len(coords) // 2} point(s); a polygon needs at least 3", "redraw the outline or delete the line")
    if not np.all(np.isfinite(coords)):
        return error("coordinate is not finite (nan/inf)", "redraw the outline or delete the line")
    polygon = coords.reshape(-1, 2)
    problems: list[Problem] = []
    low, high = float(polygon.min()), float(polygon.max())
    if low < -COORD_TOLERANCE or high > 1 + COORD_TOLERANCE:
        return error(f"coordinates outside [0, 1] (min {low:.4f}, max {high:.4f}): are they in pixels?",
                     "normalise x by the image width and y by its height")
    if low < 0 or high > 1:
        problems.append(Problem("warning", path, number, f"coordinates slightly outside [0, 1] ({low:.4f}..{high:.4f})",
                                "they are clipped to the image; `--fix` writes them clipped"))
        polygon = np.clip(polygon, 0.0, 1.0)
    if polygon_area(polygon) < MIN_NORMALISED_AREA:
        return error("polygon has zero area", "redraw the outline or delete the line")
    return Instance(cls, polygon), problems


def unread_entries(problems: list[Problem]) -> tuple[int, int]:
    """(entries not read, boxes among them) from the problems of one label file or one image's annotations: each
    error is an entry left out (a label file that cannot be read counts as one)."""
    errors = [p for p in problems if p.severity == "error"]
    return len(errors), sum(BOX_ONLY in p.message for p in errors)


def format_label_line(class_id: int, polygon: np.ndarray) -> str:
    """One label line with 6-decimal normalised coordinates."""
    return " ".join([str(class_id)] + [f"{v:.6f}" for v in np.clip(polygon, 0.0, 1.0).reshape(-1)])
