"""``poles check``: validate a dataset, summarise it, and write a cleaned copy on request."""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
from rich.console import Console
from rich.table import Table
from tqdm import tqdm

from detector.datasets.io import DatasetWriter, load_dataset
from detector.datasets.model import SPLITS, Dataset, DatasetError, Problem, Sample
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


def check_dataset(path: str | Path, progress: bool = True) -> CheckReport:
    """Read a dataset and decode every image; problems found are added to ``report.problems``."""
    try:
        dataset = load_dataset(path)
    except DatasetError as exc:
        return CheckReport(Dataset(Path(path), [], exc.problems))
    report = CheckReport(dataset, sizes={split: Counter() for split in SPLITS})
    images = [s for s in dataset.samples if s.image is not None]
    for sample in tqdm(images, desc="decoding images", unit="img", disable=not progress, leave=False):
        size = _image_size(sample, dataset.problems)
        if size is None:
            report.unreadable.add(sample.image)
        else:
            report.sizes[sample.split][f"{size[0]}x{size[1]}"] += 1
    return report


def _image_size(sample: Sample, problems: list[Problem]) -> tuple[int, int] | None:
    data = np.fromfile(sample.image, np.uint8)
    image = cv2.imdecode(data, cv2.IMREAD_COLOR) if data.size else None
    truncated = sample.image.suffix.lower() in (".jpg", ".jpeg") and data[-2:].tobytes() != b"\xff\xd9"
    if image is None:
        what = "JPEG is truncated (no end marker) and" if truncated else "image"
        problems.append(Problem("error", sample.image, None, f"{what} cannot be decoded (corrupt or not an image)",
                                "re-export or delete the image and its label"))
        return None
    if truncated:
        problems.append(Problem("warning", sample.image, None, "JPEG is truncated (no end marker); its bottom may be grey",
                                "re-export the image; `--fix` re-encodes what decodes"))
    return image.shape[1], image.shape[0]


def print_report(report: CheckReport, console: Console | None = None, show_notes: bool = False) -> None:
    """Print the per-split table (images, negatives, instances per class, image sizes) and every problem."""
    console = console or Console()
    table = Table(title=f"dataset {report.dataset.root}")
    for column in ("split", "images", "empty", *CLASSES, "poles", "image sizes"):
        table.add_column(column, justify="left" if column in ("split", "image sizes") else "right")
    for split in SPLITS:
        samples = report.dataset.split(split)
        if not samples:
            continue
        per_class = Counter(i.cls for s in samples for i in s.instances)
        negatives = sum(1 for s in samples if not s.instances)
        sizes = ", ".join(f"{k} ({v})" for k, v in report.sizes.get(split, Counter()).most_common(3))
        table.add_row(split, str(len(samples)), str(negatives), *(str(per_class[c]) for c in CLASSES),
                      str(sum(per_class.values())), sizes)
    console.print(table)
    shown = [p for p in report.problems if show_notes or p.severity != "note"]
    notes = len(report.problems) - len(shown)
    for problem in shown:
        style = "red" if problem.severity == "error" else "yellow"
        console.print(f"[{style}]{problem}[/{style}]", highlight=False, soft_wrap=True)
    counts = Counter(p.severity for p in report.problems)
    console.print(f"{counts['error']} error(s), {counts['warning']} warning(s), {counts['note']} note(s)"
                  + (f" ({notes} notes hidden: --notes shows them)" if notes else ""))


def write_fixed_copy(report: CheckReport, out: str | Path, force: bool = False) -> Path:
    """Write a cleaned copy: bad label lines dropped, coordinates clipped, unreadable images and orphan labels left out.

    Stems that collide across splits keep their first split only. The input is never written.
    """
    seen: set[str] = set()
    with DatasetWriter(out, force=force, protect=(report.dataset.root,)) as writer:
        for sample in report.dataset.samples:
            if sample.image is None or sample.image in report.unreadable or sample.stem in seen:
                continue
            seen.add(sample.stem)
            encoded = _reencode_if_truncated(sample.image)
            writer.add(sample.split, sample.image.name, encoded, sample.instances)
    return writer.out


def _reencode_if_truncated(path: Path) -> bytes | Path:
    data = np.fromfile(path, np.uint8)
    if path.suffix.lower() in (".jpg", ".jpeg") and data[-2:].tobytes() != b"\xff\xd9":
        ok, encoded = cv2.imencode(".jpg", cv2.imdecode(data, cv2.IMREAD_COLOR), [cv2.IMWRITE_JPEG_QUALITY, 95])
        return encoded.tobytes()
    return path
