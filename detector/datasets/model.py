"""In-memory model of an annotated dataset and of the problems found while reading it."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

#: Split folder names in the Roboflow layout, in the order they are reported.
SPLITS: tuple[str, ...] = ("train", "valid", "test")
#: File suffixes read as images.
IMAGE_SUFFIXES = {".jpg", ".jpeg", ".png", ".bmp", ".webp", ".tif", ".tiff"}

Severity = Literal["error", "warning", "note"]


@dataclass(frozen=True)
class Problem:
    """One thing wrong with a dataset, located to the file (and line) with the fix to apply."""

    severity: Severity
    path: Path
    line: int | None
    message: str
    fix: str

    def __str__(self) -> str:
        where = f"{self.path}:{self.line}" if self.line else str(self.path)
        return f"{where}: {self.severity}: {self.message} - fix: {self.fix}"


class DatasetError(Exception):
    """A dataset cannot be used as it is; the message lists every blocking problem."""

    def __init__(self, problems: list[Problem]):
        self.problems = problems
        shown = "\n".join(f"  {p}" for p in problems[:20])
        more = f"\n  ... and {len(problems) - 20} more" if len(problems) > 20 else ""
        super().__init__(f"{len(problems)} problem(s) in the dataset:\n{shown}{more}\n"
                         "Run `poles check DATA` for the full report, or `poles check DATA --fix --out CLEAN`.")


#: What a command raises for input it cannot use: one line for the user, never a traceback.
BAD_INPUT_ERRORS = (DatasetError, ValueError, OSError)


@dataclass
class Instance:
    """One annotated landmark: canonical class code and polygon (N, 2) in normalised image coordinates."""

    cls: str
    polygon: np.ndarray

    def pixels(self, width: int, height: int) -> np.ndarray:
        """The polygon in pixel coordinates."""
        return self.polygon * np.array([width, height], dtype=np.float64)


@dataclass
class Sample:
    """One image of a split with its label file (None for an unlabelled image, or one read from COCO JSON) and
    instances. ``unread``: its label entries that were not read as poles (boxes, classes that name no landmark,
    broken lines; each is a problem of the dataset), ``boxes`` the bounding boxes among them."""

    split: str
    image: Path | None
    label: Path | None
    instances: list[Instance] = field(default_factory=list)
    unread: int = 0
    boxes: int = 0

    @property
    def negative(self) -> bool:
        """A frame labelled as showing no landmark: nothing in its labels, read or unread."""
        return not self.instances and not self.unread

    @property
    def stem(self) -> str:
        return (self.image or self.label).stem  # type: ignore[union-attr]


@dataclass
class Dataset:
    """A dataset read from disk: its root, the class names it declares (canonical codes) and its samples."""

    root: Path
    samples: list[Sample]
    problems: list[Problem] = field(default_factory=list)
    #: Folders the dataset names beside its root (data.yaml's ``path:``), read from like the root itself.
    named_folders: tuple[Path, ...] = ()

    def split(self, name: str) -> list[Sample]:
        """The samples of one split (``train``, ``valid`` or ``test``) that have an image."""
        return [s for s in self.samples if s.split == name and s.image is not None]

    @property
    def errors(self) -> list[Problem]:
        return [p for p in self.problems if p.severity == "error"]

    def input_folders(self) -> tuple[Path, ...]:
        """Every folder this dataset is read from (its root, each split's image and label folders, wherever data.yaml's
        ``path:`` puts them): outputs may neither be nor hold nor lie inside any of them."""
        folders = {Path(self.root).resolve(), *(Path(folder).resolve() for folder in self.named_folders)}
        for sample in self.samples:
            for file in (sample.image, sample.label):
                if file is not None:
                    folders.add(file.parent.resolve())
                    if file.parent.name in ("images", "labels"):
                        folders.add(file.parent.parent.resolve())
        return tuple(sorted(folders))
