"""``poles augment``: keep every training image and add N augmented copies; valid and test are copied unchanged."""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from augment.config import THESIS_COPIES, AugmentConfig
from augment.pipeline import augment_copy, choose_operations
from detector.console import show_progress
from detector.datasets.intake import open_dataset
from detector.datasets.io import DatasetWriter
from detector.datasets.model import Instance, Sample
from detector.parallel import default_workers, ordered_map
from detector.preview import contact_sheet, draw_instances
from detector.records import JsonRecord
from detector.formats import stamped

#: Originals shown in ``augment_preview.png``, each beside at most ``PREVIEW_COPIES`` of its copies.
PREVIEW_ORIGINALS, PREVIEW_COPIES = 4, 3


@dataclass(frozen=True)
class AugmentSummary(JsonRecord):
    """What ``poles augment`` wrote (also ``augment.json`` in its output)."""

    copies: int
    seed: int
    config: AugmentConfig
    train_images_in: int
    train_images_out: int
    #: Labelled poles of the originals that were copied, the poles the copies kept and those clipped away.
    instances_into_copies: int
    instances_kept: int
    instances_dropped: int
    #: How often each operation was drawn.
    operations: dict[str, int]
    #: The contact sheet of originals and copies, when one was asked for.
    preview: Path | None = None


@dataclass(frozen=True)
class _Task:
    sample: Sample
    index: int
    copies: int
    seed: int
    config: AugmentConfig


@dataclass
class _Copy:
    filename: str
    jpeg: bytes
    instances: list[Instance]
    operations: list[str]
    dropped: int


def _augment_sample(task: _Task) -> list[_Copy]:
    """All copies of one training image; depends only on (seed, image index, copy index)."""
    image = cv2.imread(str(task.sample.image), cv2.IMREAD_COLOR)
    copies = []
    for k in range(task.copies):
        rng = np.random.default_rng([task.seed, task.index, k])
        operations = choose_operations(rng, task.config)
        copy = augment_copy(image, task.sample.instances, operations, task.config, seed=int(rng.integers(2**31)))
        ok, encoded = cv2.imencode(".jpg", copy.image, [cv2.IMWRITE_JPEG_QUALITY, 92])
        copies.append(_Copy(f"{task.sample.stem}_aug{k + 1}.jpg", encoded.tobytes(), copy.instances, operations, copy.dropped))
    return copies


def augment_once(sample: Sample, seed: int = 0, config: AugmentConfig = AugmentConfig()) -> bytes:
    """One augmented copy of a training frame, encoded as ``augment_dataset`` writes each (what one costs)."""
    return _augment_sample(_Task(sample, 0, 1, seed, config))[0].jpeg


def augment_dataset(data: str | Path, out: str | Path, *, copies: int = THESIS_COPIES, seed: int = 0,
                    config: AugmentConfig = AugmentConfig(), preview: bool = False, force: bool = False,
                    workers: int | None = None, progress: bool = True) -> AugmentSummary:
    """Write the augmented dataset to ``out``; returns what was written (also ``augment.json`` there)."""
    if copies < 0:
        raise ValueError(f"--copies must be 0 or more, not {copies}")
    dataset = open_dataset(data, progress=progress)
    train = dataset.split("train")
    if not train:
        raise ValueError(f"{dataset.root}: the train split is empty: nothing to augment")
    into = kept = dropped = 0
    operations: Counter[str] = Counter()
    tiles, preview_columns = [], 1 + min(copies, PREVIEW_COPIES)
    tasks = (_Task(sample, index, copies, seed, config) for index, sample in enumerate(train))
    with DatasetWriter(out, force=force, protect=dataset.input_folders()) as writer:
        for sample in dataset.samples:
            if sample.image is not None:
                writer.copy_sample(sample)
        results = ordered_map(_augment_sample, tasks, workers or default_workers(len(train)), chunksize=2)
        augmented = show_progress(zip(train, results), "augmenting", "img", total=len(train), enabled=progress)
        for sample, made in augmented:
            for copy in made:
                writer.add("train", copy.filename, copy.jpeg, copy.instances)
                into += len(sample.instances)
                kept += len(copy.instances)
                dropped += copy.dropped
                operations.update(copy.operations)
            if preview and len(tiles) < PREVIEW_ORIGINALS * preview_columns and sample.instances:
                tiles += _preview_row(sample, made, preview_columns)
        truth = dataset.root / "annotations.json"  # per-image truth of the originals (copies have none)
        if truth.is_file():
            writer.write_text(truth.name, truth.read_text(encoding="utf-8"))
        sheet = writer.out / "augment_preview.png" if preview and tiles else None
        summary = AugmentSummary(copies, seed, config, len(train), writer.counts["train"], into, kept, dropped,
                                 dict(operations), sheet)
        writer.write_json("augment.json", stamped("augment", summary.to_json()))
    if sheet is not None:
        contact_sheet(tiles, sheet, columns=preview_columns)
    return summary


def _preview_row(sample: Sample, made: list[_Copy], columns: int) -> list[tuple[np.ndarray, str]]:
    """The original and its first ``columns - 1`` copies, outlines drawn, each captioned with its operations; blank
    tiles where an image made fewer copies (all of its poles clipped away)."""
    original = cv2.imread(str(sample.image), cv2.IMREAD_COLOR)
    row = [(draw_instances(original, sample.instances), f"original {sample.stem}")]
    for copy in made[:columns - 1]:
        image = cv2.imdecode(np.frombuffer(copy.jpeg, np.uint8), cv2.IMREAD_COLOR)
        row.append((draw_instances(image, copy.instances), " + ".join(copy.operations)))
    return row + [(np.zeros_like(original), "")] * (columns - len(row))
