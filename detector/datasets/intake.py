"""How every command takes a dataset in: read it (YOLO layout or COCO), run ``poles check``'s rules on it, image
decoding included, and refuse it with every blocking problem when they find errors. Nothing downstream meets data
that ``poles check`` would reject.

``training_view`` gives Ultralytics a dataset it can read without touching the input: a folder inside the run with
links to the images and label files written by class name in the canonical order (copies where links are not
allowed). Ultralytics' ``labels.cache`` files land there, never in the user's dataset.
"""
from __future__ import annotations

import sys
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from pathlib import Path

from detector.datasets.check import check_dataset, refusal_advice
from detector.datasets.io import DatasetWriter
from detector.datasets.model import Dataset, DatasetError, Problem, grouped_problems, problem_kind

#: Splits Ultralytics needs to train (it validates every epoch).
TRAINING_SPLITS = ("train", "valid")


#: The kinds of warning said so far inside ``each_warning_once`` (None outside it: every call says its own).
_said_kinds: ContextVar[set | None] = ContextVar("said_kinds", default=None)


@contextmanager
def each_warning_once() -> Iterator[None]:
    """Within it, each kind of dataset warning is said once: a command that reads the user's export and then its
    own copies of it (a fine-tune) does not repeat the export's warnings for each copy."""
    token = _said_kinds.set(set())
    try:
        yield
    finally:
        _said_kinds.reset(token)


def open_dataset(path: str | Path, renames: dict[str, str] | None = None, progress: bool = True) -> Dataset:
    """The dataset at ``path`` after every check (images decoded); ``DatasetError`` listing what blocks it. What
    does not block it (a truncated JPEG, a turned or square frame) is said on standard error, one line a kind."""
    report = check_dataset(path, progress=progress, renames=renames)
    if report.errors:
        raise DatasetError(report.errors, refusal_advice(report.errors))
    said = _said_kinds.get()
    for group in grouped_problems([p for p in report.problems if p.severity == "warning"]):
        if said is not None and problem_kind(group[0]) in said:
            continue
        if said is not None:
            said.add(problem_kind(group[0]))
        more = f" (and {len(group) - 1} more like it)" if len(group) > 1 else ""
        print(f"{group[0]}{more}", file=sys.stderr)
    return report.dataset


def training_view(dataset: Dataset, folder: Path) -> Path:
    """Write the view of ``dataset`` that Ultralytics trains on into ``folder``; returns its data.yaml."""
    for split in TRAINING_SPLITS:
        if not dataset.split(split):
            raise DatasetError([Problem("error", dataset.root, None, f"the {split} split has no images: training needs "
                                        "train and valid", "run `poles split --data DATA --out NEW` to make them")])
    with DatasetWriter(folder, force=True, protect=dataset.input_folders()) as writer:
        for sample in dataset.samples:
            if sample.image is not None:
                writer.add(sample.split, sample.image.name, sample.image, sample.instances, link=True)
    return folder / "data.yaml"
