"""What an evaluation found, as typed values: counts per frame and in all, the confidence sweep, recall by pole
width, the confusion matrix, range and bearing errors - the content of ``poles evaluate``'s metrics.json."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from detector.records import JsonRecord


@dataclass(frozen=True)
class Counts(JsonRecord):
    """TP, FP, FN and TN as the thesis counted them (TN: a frame with no label and no detection)."""

    tp: int = 0
    fp: int = 0
    fn: int = 0
    tn: int = 0

    def __add__(self, other: Counts) -> Counts:
        return Counts(self.tp + other.tp, self.fp + other.fp, self.fn + other.fn, self.tn + other.tn)

    def precision_recall(self) -> tuple[float, float, float]:
        """Precision, recall and F1. With no detections, precision is 1 only if there was nothing to find; with no
        labels, recall is 1."""
        precision = self.tp / (self.tp + self.fp) if self.tp + self.fp else float(self.fn == 0)
        recall = self.tp / (self.tp + self.fn) if self.tp + self.fn else 1.0
        f1 = 2 * precision * recall / (precision + recall) if precision + recall else 0.0
        return precision, recall, f1


@dataclass(frozen=True)
class FrameCounts(JsonRecord):
    """One frame's counts."""

    image: str
    counts: Counts


@dataclass(frozen=True)
class SweepPoint(JsonRecord):
    """Precision, recall and F1 at one confidence threshold."""

    conf: float
    precision: float
    recall: float
    f1: float


@dataclass(frozen=True)
class WidthRecall(JsonRecord):
    """Labels in one pole-width bin and how many were found; recall None for an empty bin."""

    width: str
    labels: int
    found: int

    @property
    def recall(self) -> float | None:
        return self.found / self.labels if self.labels else None


@dataclass(frozen=True)
class MapScores(JsonRecord):
    """COCO-style mean average precision at IoU 0.5 and over 0.5-0.95."""

    map50: float
    map50_95: float


@dataclass(frozen=True)
class ErrorStats(JsonRecord):
    """Mean, median and 90th percentile of absolute errors, and how many there were."""

    mean: float
    median: float
    p90: float
    count: int


@dataclass(frozen=True)
class Confusion(JsonRecord):
    """Counts by true class (rows) and detected class (columns), "none" last in both."""

    labels: tuple[str, ...]
    counts: tuple[tuple[int, ...], ...]


@dataclass(frozen=True)
class Evaluation(JsonRecord):
    """One front end on one split of a dataset at one threshold (``poles evaluate``'s metrics.json)."""

    model: str
    data: Path
    split: str
    conf: float
    images: int
    #: How a detection is matched to a label: ``mask`` or ``box`` IoU >= 0.5, or the band-dividing ``point``.
    matching: str
    #: Frames the front end was given the camera pose of.
    camera_poses: int
    counts: Counts
    precision: float
    recall: float
    f1: float
    #: Mean IoU of the true positives (None for the colour filter, matched by point).
    mean_iou: float | None
    best_f1_conf: float
    best_f1: float
    sweep: tuple[SweepPoint, ...]
    per_image: tuple[FrameCounts, ...]
    confusion: Confusion
    class_swaps: int
    duplicates: int
    recall_by_width: tuple[WidthRecall, ...]
    map: MapScores | None
    #: Range (m), bearing (deg) and, for the colour filter, band-divide (px) errors of the true positives.
    range_error: ErrorStats | None
    bearing_error: ErrorStats | None
    divide_pixel_error: ErrorStats | None
    #: Error overlays written.
    overlays: int
