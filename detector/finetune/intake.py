"""The team's export as ``poles finetune`` trains on it: checked as every command checks a dataset, copied into the
run in this project's class order, and given a valid split when it has none (the blend share is chosen on it).
The export itself is only read."""
from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

from detector.datasets.intake import open_dataset
from detector.datasets.io import DatasetWriter, SplitCounts
from detector.datasets.model import Sample
from detector.datasets.split import stratified_assignment
from detector.records import JsonRecord

#: Share of the train split moved to valid when the export has no valid split (at least one frame).
VALID_SHARE = 0.2


@dataclass(frozen=True)
class DatasetIntake(JsonRecord):
    """The team's annotated export as the fine-tune took it in: where it was read, frames per split, and poles."""

    source: Path
    frames: SplitCounts
    #: Whether the valid split was made from train frames (the export had none).
    valid_made_from_train: bool
    poles: int


def prepare_dataset(annotated: Path, out: Path, renames: dict[str, str] | None, seed: int,
                    more_train: Path | None = None) -> DatasetIntake:
    """Copy the ``annotated`` export into ``out`` (replaced), splitting its train frames into train and valid when it
    has no valid frames; ``more_train`` (a dataset: the teacher's labels) adds every frame of its own to train
    (named ``unlabelled_*``), so an export of held-out frames alone is enough beside it. Returns frames per split and
    what was done. Refuses an export without frames to train on."""
    dataset = open_dataset(annotated, renames)
    train, valid, test = (dataset.split(name) for name in ("train", "valid", "test"))
    taught = [replace(sample, split="train") for sample in open_dataset(more_train).samples] \
        if more_train is not None else []
    taught_ids = {id(sample) for sample in taught}
    train = train + taught
    if not train:
        held = ", ".join(f"{name} {len(dataset.split(name))}" for name in ("valid", "test") if dataset.split(name))
        raise ValueError(f"{annotated}: no frame in the train split ({held or 'no frames at all'}) - fine-tuning needs "
                         "frames to train on: re-export with a train split, or run `poles split --data "
                         f"{annotated} --out NEW` and fine-tune NEW")
    moved = not valid
    if moved:
        if len(train) < 2:
            raise ValueError(f"{annotated}: one train frame and no valid split - annotate at least two frames (one is "
                             "kept aside to choose the blend on)")
        shares = {"train": 1.0 - VALID_SHARE, "valid": VALID_SHARE, "test": 0.0}
        assignment = stratified_assignment(train, shares, seed)  # two or more frames: valid gets at least one
        train, valid = ([s for s, a in zip(train, assignment) if a == name] for name in ("train", "valid"))
    with DatasetWriter(out, force=True, protect=dataset.input_folders()) as writer:
        for split, samples in (("train", train), ("valid", valid), ("test", test)):
            for sample in samples:
                if id(sample) in taught_ids:
                    writer.add(split, f"unlabelled_{sample.image.name}", sample.image, sample.instances)
                else:
                    writer.copy_sample(Sample(split, sample.image, sample.label, sample.instances))
    poles = sum(len(s.instances) for s in train + valid + test if id(s) not in taught_ids)
    return DatasetIntake(annotated, writer.frames, moved, poles)
