"""In-memory model of an annotated dataset and of the problems found while reading it."""
from __future__ import annotations

import re
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


#: Suffixes of the files that describe a whole dataset: a problem with one of them (no line) is a root cause.
DESCRIPTION_SUFFIXES = {".yaml", ".yml", ".json"}
#: Kinds of problem a refusal names before it points to ``poles check`` for the rest.
SHOWN_KINDS = 6
#: What a refusal ends with by default: where to see every problem.
CHECK_ADVICE = "`poles check DATA` lists every problem with its file, line and fix"


def problem_kind(problem: Problem) -> tuple[str, str]:
    """What a problem is, without its particulars (quoted names, numbers): its severity and message's shape."""
    return problem.severity, re.sub(r"'[^']*'|\"[^\"]*\"|-?\d+(\.\d+)?", "#", problem.message)


def is_root_cause(problem: Problem) -> bool:
    """Whether a problem concerns the dataset as a whole: its data.yaml, COCO file or folder, not one line or image
    (a COCO file's problems with one annotation are per entry)."""
    whole_file = Path(problem.path).suffix.lower() in DESCRIPTION_SUFFIXES or not Path(problem.path).suffix
    return problem.line is None and whole_file and not problem.message.startswith("annotation ")


def grouped_problems(problems: list[Problem]) -> list[list[Problem]]:
    """Problems grouped by kind, root causes first: errors before warnings before notes; within each, the kinds
    that concern the whole dataset in the order they were found (a reader finds the cause before its effects), then
    the rest, largest first."""
    groups: dict[tuple[str, str], list[Problem]] = {}
    for problem in problems:
        groups.setdefault(problem_kind(problem), []).append(problem)
    severity_order = {"error": 0, "warning": 1, "note": 2}
    return sorted(groups.values(), key=lambda group: (severity_order[group[0].severity], not is_root_cause(group[0]),
                                                      0 if is_root_cause(group[0]) else -len(group)))


class DatasetError(Exception):
    """A dataset cannot be used as it is. The message's first line is the root cause and its fix; the other kinds
    of problem follow, one line each with a count and an example; ``advice`` ends it (None: nothing more to say)."""

    def __init__(self, problems: list[Problem], advice: str | None = CHECK_ADVICE):
        self.problems = problems
        groups = grouped_problems(problems)
        lines = [str(groups[0][0]) if groups else "the dataset cannot be used"]
        for index, group in enumerate(groups[:SHOWN_KINDS]):
            rest = group[1:] if index == 0 else group
            if rest:
                lead = f"{len(rest):,} more like it" if index == 0 else f"{len(rest):,} x"
                lines.append(f"  {lead}: {rest[0]}")
        if len(groups) > SHOWN_KINDS:
            lines.append(f"  and {sum(len(g) for g in groups[SHOWN_KINDS:]):,} problem(s) of "
                         f"{len(groups) - SHOWN_KINDS} other kind(s)")
        if advice and not (len(problems) == 1 and advice == CHECK_ADVICE):  # one problem: nothing more to list
            lines.append(advice)
        super().__init__("\n".join(lines))


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
