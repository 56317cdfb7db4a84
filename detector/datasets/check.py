"""``poles check``: validate a dataset, summarise it, and write a cleaned copy on request."""
from __future__ import annotations

import os
import tempfile
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
from rich.console import Console
from rich.table import Table

from detector.console import make_console, show_progress
from detector.datasets.io import DatasetWriter, load_dataset
from detector.datasets.jpeg import truncated_jpeg
from detector.datasets.labels import BOX_ONLY
from detector.datasets.model import (CHECK_ADVICE, IMAGE_SUFFIXES, SPLITS, Dataset, DatasetError, Problem, Sample,
                                     grouped_problems, is_root_cause)
from detector.datasets.names import UNNAMED_CLASS_OUTLINES
from detector.datasets.orientation import UPRIGHT, encoded_orientation
from detector.atomic import write_text
from detector.outputs import fresh_path
from naoslam.landmarks import CLASSES


@dataclass
class CheckReport:
    """What ``check_dataset`` found: the dataset, every problem, image sizes, and the images that cannot be read."""

    dataset: Dataset
    sizes: dict[str, Counter] = field(default_factory=dict)
    unreadable: set[Path] = field(default_factory=set)

    @property
    def problems(self) -> list[Problem]:
        return self.dataset.problems

    @property
    def errors(self) -> list[Problem]:
        return self.dataset.errors


def check_dataset(path: str | Path, progress: bool = True, renames: dict[str, str] | None = None) -> CheckReport:
    """Read a dataset and decode every image; problems found are added to ``report.problems``."""
    try:
        dataset = load_dataset(path, renames)
    except DatasetError as exc:
        return CheckReport(Dataset(Path(path), [], exc.problems))
    report = CheckReport(dataset, sizes={split: Counter() for split in SPLITS})
    images = [s for s in dataset.samples if s.image is not None]
    shapes: set[tuple[int, int]] = set()
    for sample in show_progress(images, "decoding images", "img", enabled=progress, leave=False):
        size = _image_size(sample, dataset.problems)
        if size is None:
            report.unreadable.add(sample.image)
        else:
            report.sizes[sample.split][f"{size[0]}x{size[1]}"] += 1
            shapes.add(size)
    squeezed = _squeezed_frames(dataset.root, shapes)
    if squeezed:
        dataset.problems.append(squeezed)
    return report


def _squeezed_frames(root: Path, shapes: set[tuple[int, int]]) -> Problem | None:
    """A warning when every image is square: the Nao's frames are 4:3, and a square export is most likely a
    Roboflow "Resize: Stretch to" step, which makes poles taller than the robot sees them."""
    if not shapes or any(width != height for width, height in shapes):
        return None
    sizes = ", ".join(f"{width}x{height}" for width, height in sorted(shapes))
    return Problem("warning", root, None, f"every image is square ({sizes}): the Nao's 4:3 frames "
                   "stretched to a square (a Roboflow 'Resize: Stretch to' step) show poles 4/3 too tall for their "
                   "width, so a model trained and ranges measured on them are off",
                   "export again without the Resize step (Roboflow: Preprocessing); nothing if your camera's frames "
                   "are square")


#: The smallest image side a frame may have: a pole is a few pixels wide even far away, and a frame smaller than
#: this is a thumbnail or a broken export.
MIN_FRAME_SIDE = 16


def _image_size(sample: Sample, problems: list[Problem]) -> tuple[int, int] | None:
    try:
        data = np.fromfile(sample.image, np.uint8)
    except OSError as exc:
        problems.append(Problem("error", sample.image, None, f"cannot be read ({exc.strerror})", "replace it with an image"))
        return None
    image = cv2.imdecode(data, cv2.IMREAD_COLOR) if data.size else None
    truncated = truncated_jpeg(data.tobytes())
    if image is None:
        what = "JPEG is truncated (no end marker) and" if truncated else "image"
        problems.append(Problem("error", sample.image, None, f"{what} cannot be decoded (corrupt or not an image)",
                                "re-export or delete the image and its label"))
        return None
    if min(image.shape[:2]) < MIN_FRAME_SIDE:
        problems.append(Problem("error", sample.image, None, f"image is {image.shape[1]}x{image.shape[0]} px: too "
                                f"small to show a pole (at least {MIN_FRAME_SIDE} px a side)",
                                "re-export it at the camera's size, or delete it and its label"))
        return None
    if truncated:
        problems.append(Problem("warning", sample.image, None, "JPEG is truncated (no end marker); its bottom may be grey",
                                "re-export the image; `--fix` re-encodes what decodes"))
    orientation = encoded_orientation(data.tobytes())
    if orientation != UPRIGHT:
        problems.append(Problem("warning", sample.image, None, f"stored turned or mirrored (EXIF orientation "
                                f"{orientation}); it is read upright everywhere, so its outlines must have been drawn "
                                "on the upright image", "nothing if they were (Roboflow's Auto-Orient does it); "
                                "`--fix` writes the image upright without the tag"))
    return image.shape[1], image.shape[0]


#: Examples shown per kind of problem; the whole list goes to a file.
EXAMPLES_PER_KIND = 3


def print_report(report: CheckReport, console: Console | None = None, show_notes: bool = False,
                 full_list: Path | None = None) -> Path | None:
    """Print the per-split table and a summary per kind of problem (count and first examples); the whole list is
    written to ``full_list`` (atomically) when the summary leaves some out. Returns that file, if written."""
    console = console or make_console()
    if report.dataset.samples:
        console.print(_split_table(report))
    shown = [p for p in report.problems if show_notes or p.severity != "note"]
    left_out = 0
    for problems in grouped_problems(shown):
        severity = problems[0].severity
        style = "red" if severity == "error" else "yellow"
        console.print(f"[{style}]{len(problems)} x {severity}: {problems[0].message} - fix: {problems[0].fix}[/{style}]",
                      highlight=False, soft_wrap=True)
        for problem in problems[:EXAMPLES_PER_KIND]:
            where = f"{problem.path}" + (f":{problem.line}" if problem.line else "")
            particulars = f"  ({problem.message})" if problem.message != problems[0].message else ""
            console.print(f"    {where}{particulars}", highlight=False, soft_wrap=True)
        left_out += max(0, len(problems) - EXAMPLES_PER_KIND)
    counts = Counter(p.severity for p in report.problems)
    notes = len(report.problems) - len(shown)
    console.print(f"{counts['error']} error(s), {counts['warning']} warning(s), {counts['note']} note(s)"
                  + (f" ({notes} notes hidden: --notes shows them)" if notes else ""))
    if left_out and full_list is not None:
        full_list = fresh_path(full_list)  # a check reads: it never replaces a file
        write_text(full_list, "".join(f"{p}\n" for p in report.problems))
        console.print(f"every problem, one per line: {full_list}")
        return full_list
    return None


def _split_table(report: CheckReport) -> Table:
    """One row per split: images, frames labelled empty, frames whose labels give no pole (box-only ones apart),
    unreadable images, poles per class, image sizes."""
    table = Table(title=f"dataset {report.dataset.root}")
    for column in ("split", "images", "empty", "box-only", "no pole read", "unreadable", *CLASSES, "poles",
                   "image sizes"):
        table.add_column(column, justify="left" if column in ("split", "image sizes") else "right")
    for split in SPLITS:
        samples = report.dataset.split(split)
        if not samples:
            continue
        per_class = Counter(i.cls for s in samples for i in s.instances)
        unlabelled = [s for s in samples if not s.instances]
        negatives = sum(s.negative for s in unlabelled)
        boxes = sum(1 for s in unlabelled if s.boxes)
        unread = sum(1 for s in unlabelled if s.unread and not s.boxes)
        unreadable = sum(1 for s in samples if s.image in report.unreadable)
        sizes = ", ".join(f"{k} ({v})" for k, v in report.sizes.get(split, Counter()).most_common(3))
        table.add_row(split, str(len(samples)), str(negatives), str(boxes), str(unread), str(unreadable),
                      *(str(per_class[c]) for c in CLASSES), str(sum(per_class.values())), sizes)
    return table


def listing_path(dataset: Dataset, fixed_copy: Path | None = None) -> Path:
    """Where the whole list of problems goes: ``CLEAN.check.txt`` beside a ``--fix`` copy, else
    ``check-<dataset>.txt`` in the working folder, or beside the dataset when run from inside it (never into it), or
    in the system's temporary folder when that folder cannot be written; numbered (``check-<dataset>-2.txt``) where
    a file of that name is there already."""
    if fixed_copy is not None:
        return Path(f"{fixed_copy}.check.txt")
    root, here = Path(dataset.root).resolve(), Path.cwd().resolve()
    inside = any(here == folder or folder in here.parents for folder in dataset.input_folders())
    folder = root.parent if inside else here
    if not os.access(folder, os.W_OK):
        folder = Path(tempfile.gettempdir())
    return folder / f"check-{root.name}.txt"


def refusal_advice(errors: list[Problem]) -> str:
    """How a refused dataset's problems are all seen, and whether ``--fix`` would clear them: it drops broken label
    lines and images that cannot be read, but cannot draw outlines for boxes, name classes or mend data.yaml."""
    if any(is_root_cause(p) or BOX_ONLY in p.message or UNNAMED_CLASS_OUTLINES in p.message for p in errors):
        return CHECK_ADVICE
    if all(p.line is not None or Path(p.path).suffix.lower() in IMAGE_SUFFIXES for p in errors):
        return f"{CHECK_ADVICE}; `poles check DATA --fix --out CLEAN` writes a copy without them"
    return CHECK_ADVICE


def unnamed_classes(problems: list[Problem]) -> set[str]:
    """The classes (as their refusals name them) whose outlines name no landmark: a COCO export refuses one class
    once per split's annotations file, and counts once here."""
    return {p.message.split(UNNAMED_CLASS_OUTLINES)[0].strip() for p in problems if UNNAMED_CLASS_OUTLINES in p.message}


def write_fixed_copy(report: CheckReport, out: str | Path, force: bool = False) -> Path:
    """Write a cleaned copy: bad label lines dropped, coordinates clipped, unreadable images and orphan labels left out,
    truncated JPEGs re-encoded and images stored turned (EXIF orientation) written upright.

    Stems that collide across splits keep their first split only. The input is never written. A dataset that could
    not be read at all, or whose labels are boxes, is refused: a "cleaned" copy would hold images without poles.
    """
    if not report.dataset.samples:
        raise DatasetError(report.errors, advice=None)
    boxes = [p for p in report.errors if BOX_ONLY in p.message]
    if boxes:
        raise DatasetError([boxes[0], Problem("error", report.dataset.root, None, f"--fix cannot turn {len(boxes)} "
                                              "box label(s) into outlines", "re-export the dataset")], advice=None)
    unnamed = [p for p in report.errors if UNNAMED_CLASS_OUTLINES in p.message]
    if unnamed:  # dropping them would leave a copy that passes `check` and trains on fewer poles, or none
        classes = len(unnamed_classes(unnamed))
        raise DatasetError([*unnamed, Problem("error", report.dataset.root, None, f"--fix does not delete the "
                                              f"outlines of {classes} class(es) that name no landmark",
                                              "rename them to pole codes with `poles convert --rename`, or delete "
                                              "them in Roboflow, then check again")], advice=None)
    seen: set[str] = set()
    with DatasetWriter(out, force=force, protect=report.dataset.input_folders()) as writer:
        for sample in report.dataset.samples:
            if sample.image is None or sample.image in report.unreadable or sample.stem in seen:
                continue
            seen.add(sample.stem)
            encoded = _repaired_image(sample.image)
            writer.add(sample.split, sample.image.name, encoded, sample.instances)
    return writer.out


def _repaired_image(path: Path) -> bytes | Path:
    """A truncated JPEG re-encoded from what decodes, an image stored turned written upright without its EXIF
    tag (OpenCV writes none), anything else the file itself."""
    data = np.fromfile(path, np.uint8)
    truncated = truncated_jpeg(data.tobytes())
    if not truncated and encoded_orientation(data.tobytes()) == UPRIGHT:
        return path
    quality = [cv2.IMWRITE_JPEG_QUALITY, 95] if path.suffix.lower() in (".jpg", ".jpeg") else []
    _, encoded = cv2.imencode(path.suffix, cv2.imdecode(data, cv2.IMREAD_COLOR), quality)
    return encoded.tobytes()
