"""``poles split``: re-split a dataset (thesis: 70 train / 20 test / 10 valid), stratified by class."""
from __future__ import annotations

import math
from collections import Counter
from pathlib import Path

import numpy as np

from detector.datasets.intake import open_dataset
from detector.datasets.io import DatasetWriter, SplitCounts
from detector.datasets.model import Sample
from detector.datasets.truth import read_annotations
from detector.formats import STAMP_KEYS, stamped

#: The order of ``--ratios``: train, test, valid (as the thesis lists them).
RATIO_ORDER = ("train", "test", "valid")

#: Train, test and valid fractions, as the thesis split its data.
THESIS_RATIOS = (0.7, 0.2, 0.1)


def stratified_assignment(samples: list[Sample], ratios: dict[str, float], seed: int) -> list[str]:
    """A split per sample, split sizes as the ratios say; each class spread over the splits in the same ratios.

    Images are placed rarest class first, each into the split (not yet full) that most lacks its classes.
    """
    total = sum(ratios.values())
    share = {split: r / total for split, r in ratios.items() if r > 0}
    targets = {split: int(share[split] * len(samples)) for split in share}
    for split in sorted(share, key=lambda s: share[s] * len(samples) - targets[s], reverse=True)[: len(samples) - sum(targets.values())]:
        targets[split] += 1
    if len(samples) >= len(share):  # every split asked for gets an image (a small dataset's valid split would not)
        for split in [s for s in share if targets[s] == 0]:
            targets[max(targets, key=targets.get)] -= 1
            targets[split] += 1
    kinds = [{i.cls for i in s.instances} or {"(none)"} for s in samples]  # negatives are spread like a class
    class_images = Counter(c for classes in kinds for c in classes)
    order = np.random.default_rng(seed).permutation(len(samples))
    rarity = [min(class_images[c] for c in kinds[k]) for k in order]
    order = [k for _, k in sorted(zip(rarity, order), key=lambda pair: pair[0])]
    placed = {split: Counter() for split in share}
    sizes = Counter()
    result = [""] * len(samples)
    for k in order:
        classes = kinds[k]
        open_splits = [split for split in share if sizes[split] < targets[split]]
        best = max(open_splits, key=lambda split: (sum(1 - placed[split][c] / (share[split] * class_images[c]) for c in classes),
                                                  targets[split] - sizes[split]))
        result[k] = best
        sizes[best] += 1
        placed[best].update(classes)
    return result


def split_dataset(data: str | Path, out: str | Path, ratios: tuple[float, float, float] = THESIS_RATIOS,
                  seed: int = 0, force: bool = False) -> SplitCounts:
    """Write a copy of every image of ``data`` into new splits; returns images per split. An ``annotations.json`` of
    ``poles synth`` (true ranges, camera poses) goes along, each image's entry naming its new split."""
    if len(ratios) != 3 or not all(math.isfinite(r) and r >= 0 for r in ratios):
        raise ValueError(f"--ratios needs three non-negative numbers (train test valid), got {list(ratios)}")
    if sum(ratios) <= 0:
        raise ValueError(f"--ratios {' '.join(f'{r:g}' for r in ratios)} puts every image nowhere: give at least one "
                         "split a share above 0, e.g. --ratios 0.7 0.2 0.1")
    dataset = open_dataset(data)
    samples = [s for s in dataset.samples if s.image is not None]
    assignment = stratified_assignment(samples, dict(zip(RATIO_ORDER, ratios)), seed)
    annotations = read_annotations(dataset.root / "annotations.json")
    with DatasetWriter(out, force=force, protect=dataset.input_folders()) as writer:
        for sample, split in zip(samples, assignment):
            writer.copy_sample(Sample(split, sample.image, sample.label, sample.instances))
            entry = (annotations or {}).get("images", {}).get(sample.image.name)
            if isinstance(entry, dict):
                entry["split"] = split
        if annotations is not None:
            unstamped = {key: value for key, value in annotations.items() if key not in STAMP_KEYS}
            writer.write_json("annotations.json", stamped("annotations", unstamped))
    return writer.frames
