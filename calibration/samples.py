"""Pole sizes in pixels paired with their true range: from the labels' masks or from a model's masks."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from tqdm import tqdm

from detector.datasets.intake import open_dataset
from detector.datasets.polygons import polygon_to_mask
from detector.datasets.truth import load_truth
from naoslam.detector import LandmarkDetector, mask_centre_column, rotated_box_of_mask


@dataclass(frozen=True)
class SizeSample:
    """One pole of known range, measured in one image."""

    image: str
    cls: str
    range_m: float
    width_px: float
    height_px: float
    centre_column: float
    image_width: int
    partial: bool = False
    bearing_rad: float | None = None
    band_distance_px: float | None = None


def collect_samples(data: Path, model: Path | None = None, truth_csv: Path | None = None,
                    conf: float = 0.25, progress: bool = True) -> list[SizeSample]:
    """Measure every pole with a true range: its labelled mask, or the model's best same-class detection."""
    dataset = open_dataset(data, progress=progress)
    truth = load_truth(dataset, truth_csv)
    if not any(t and t.get("range_m") is not None for entries in truth.values() for t in entries):
        raise ValueError(f"{data}: no landmark has a true range - add annotations.json (from `poles synth "
                         "--calibration-shots`) or pass --truth image,class,range_m CSV")
    detector = LandmarkDetector(model, conf=conf) if model else None
    samples = []
    for sample in tqdm(dataset.samples, desc="measuring", unit="img", disable=not progress):
        entries = truth.get(sample.image.name)
        if not entries:
            continue
        frame = cv2.imread(str(sample.image))
        height, width = frame.shape[:2]
        detections = detector(frame) if detector else None
        for instance, entry in zip(sample.instances, entries):
            if not entry or entry.get("range_m") is None:
                continue
            if detections is None:
                mask = polygon_to_mask(instance.pixels(width, height), width, height)
                box, column = rotated_box_of_mask(mask), mask_centre_column(mask) if mask.any() else None
            else:
                same = [d for d in detections if d.name == instance.cls]
                box, column = (same[0].rotated_box, same[0].centre_column) if same else (None, None)
            if box is None:
                continue
            partial = entry.get("partial")
            if partial is None:  # a truth CSV does not say: a pole whose outline reaches the border is cut
                partial = touches_border(instance.polygon)
            samples.append(SizeSample(sample.image.name, instance.cls, float(entry["range_m"]), box.width, box.height,
                                      column, width, bool(partial), entry.get("bearing_rad"),
                                      entry.get("band_centre_distance_px")))
    if not samples:
        raise ValueError(f"{data}: no pole with a true range could be measured"
                         + (f" - {model} found none of them" if model else ""))
    return samples


#: How close (normalised) an outline must come to the image border to count as cut by it.
BORDER_MARGIN = 0.002


def touches_border(polygon: np.ndarray) -> bool:
    """True when a normalised outline reaches the image border (the pole is cut, its height is not its own)."""
    return bool(polygon.min() <= BORDER_MARGIN or polygon.max() >= 1.0 - BORDER_MARGIN)


def as_arrays(samples: list[SizeSample], reference_width: int) -> dict[str, np.ndarray]:
    """Columns of the samples, pixel sizes scaled to ``reference_width``."""
    scale = np.array([reference_width / s.image_width for s in samples])
    return {"range": np.array([s.range_m for s in samples]), "width": np.array([s.width_px for s in samples]) * scale,
            "height": np.array([s.height_px for s in samples]) * scale,
            "partial": np.array([s.partial for s in samples])}
