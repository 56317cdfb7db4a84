"""Counting as the 2024 thesis did, per image: TP, FP, FN, and TN (no landmark and no detection).

A detection is a true positive when its class matches a label's and their masks overlap with IoU >= 0.5
(greedy by confidence, one detection per label). A box-only front end (the robot's two-stage one) has no mask: its
box is matched to the label's box by IoU >= 0.5, and a model with masks can be scored that way too, to compare the
two. A colour-filter detection has no real mask: it is a true positive when its band-dividing point falls inside a
same-class label (grown by 3 px).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import cv2
import numpy as np

from detector.evaluation.results import Counts, MapScores, SweepPoint
from detector.matching import box_iou, greedy_match, mask_box, mask_iou
from naoslam.perception.detections import Detection, rotated_box_of_mask

MATCH_IOU = 0.5
#: How a detection is matched to a label: by mask IoU, by box IoU, or by the band-dividing point (the colour filter).
MATCHINGS = ("mask", "box", "point")
#: IoU thresholds of the COCO-style mAP50-95.
MAP_THRESHOLDS = np.linspace(0.5, 0.95, 10)
POINT_TOLERANCE_PX = 3
#: Widths are given for a frame 640 px wide (the Nao's), so a 1280x960 frame's poles count at half their width.
REFERENCE_FRAME_WIDTH_PX = 640


@dataclass
class ImageEvaluation:
    """One image's labels, detections and their pairwise overlaps, from which counts at any threshold follow.
    Compact: no mask is kept (the detections' are dropped once the overlaps are known), so memory does not grow
    with the frames' size."""

    name: str
    truth_classes: list[str]
    #: Each label's width (px at a 640 px frame width), for recall by width.
    truth_widths: list[float]
    truth: list[dict | None]
    #: The detections, best first, without their masks.
    detections: list[Detection]
    scores: np.ndarray
    overlap: np.ndarray
    same_class: np.ndarray
    matching: str

    @property
    def classes(self) -> list[str]:
        return [d.name for d in self.detections]

    def kept(self, conf: float) -> np.ndarray:
        return np.flatnonzero(self.scores >= conf)

    def match(self, conf: float, iou: float = MATCH_IOU) -> list[tuple[int, int]]:
        """(detection, label) pairs among detections scoring >= conf."""
        kept = self.kept(conf)
        pairs = greedy_match(self.overlap[kept], self.scores[kept], iou, self.same_class[kept])
        return [(int(kept[p]), r) for p, r in pairs]

    def counts(self, conf: float) -> Counts:
        """TP, FP, FN and TN of this image at ``conf``, as the thesis counted them (TN: no label, no detection)."""
        tp = len(self.match(conf))
        kept = len(self.kept(conf))
        labels = len(self.truth_classes)
        return Counts(tp, kept - tp, labels - tp, int(labels == 0 and kept == 0))


def evaluate_image(name: str, truth_classes: list[str], truth_masks: list[np.ndarray], truth: list[dict | None],
                   detections: list[Detection], frame_shape: tuple[int, ...], matching: str = "mask") -> ImageEvaluation:
    """Overlap between every detection and label (``matching``, one of ``MATCHINGS``): mask IoU, box IoU (the box
    around each label's mask), or whether the band-dividing point lies in the label (the colour filter, whose band
    mask is not the pole's outline)."""
    if matching not in MATCHINGS:
        raise ValueError(f"matching {matching!r} is not one of {', '.join(MATCHINGS)}")
    same_class = np.array([[d.name == t for t in truth_classes] for d in detections], dtype=bool)
    same_class = same_class.reshape(len(detections), len(truth_classes))
    if matching == "point":
        kernel = np.ones((2 * POINT_TOLERANCE_PX + 1,) * 2, np.uint8)
        grown = [cv2.dilate(m.astype(np.uint8), kernel) > 0 for m in truth_masks]
        overlap = np.array([[_inside(d.divide_centre, g) for g in grown] for d in detections], dtype=float)
    elif matching == "box":
        overlap = box_iou([d.box for d in detections], [mask_box(m) for m in truth_masks])
    else:
        overlap = mask_iou([d.full_mask(frame_shape) for d in detections], truth_masks)
    overlap = overlap.reshape(len(detections), len(truth_masks))
    return ImageEvaluation(name, truth_classes, [label_width_px(m) for m in truth_masks], truth,
                           [replace(d, mask=np.zeros((0, 0), bool)) for d in detections],
                           np.array([d.confidence for d in detections], dtype=float), overlap, same_class,
                           matching)


def label_width_px(mask: np.ndarray) -> float:
    """The label's width: the short side of the rotated box around its mask, scaled to a 640 px wide frame."""
    box = rotated_box_of_mask(mask)
    return 0.0 if box is None else box.width * REFERENCE_FRAME_WIDTH_PX / mask.shape[1]


def _inside(point: tuple[float, float], mask: np.ndarray) -> bool:
    x, y = int(point[0]), int(point[1])
    return 0 <= y < mask.shape[0] and 0 <= x < mask.shape[1] and bool(mask[y, x])


def totals(images: list[ImageEvaluation], conf: float) -> Counts:
    """Summed TP, FP, FN, TN over images."""
    return sum((image.counts(conf) for image in images), Counts())


@dataclass(frozen=True)
class Outcome:
    """Where every kept detection and every label of one image went at one threshold (indices into the image's
    predictions and labels). ``swaps`` pair a leftover detection with a leftover label it overlaps (IoU >= 0.5,
    greedy by confidence) under another class; a ``duplicate`` overlaps a label already taken; a ``stray``
    overlaps none; ``missed`` labels have no detection at all."""

    matches: list[tuple[int, int]]
    swaps: list[tuple[int, int]]
    duplicates: list[int]
    strays: list[int]
    missed: list[int]


def outcome(image: ImageEvaluation, conf: float) -> Outcome:
    """The image's detections and labels at ``conf``, sorted into matches, swaps, duplicates, strays and misses."""
    matches = image.match(conf)
    taken_p, taken_r = {p for p, _ in matches}, {r for _, r in matches}
    left_p = np.array([p for p in image.kept(conf) if p not in taken_p], dtype=int)
    left_r = np.array([r for r in range(len(image.truth_classes)) if r not in taken_r], dtype=int)
    pairs = greedy_match(image.overlap[np.ix_(left_p, left_r)], image.scores[left_p], MATCH_IOU)
    swaps = [(int(left_p[i]), int(left_r[j])) for i, j in pairs]
    swapped_p, swapped_r = {p for p, _ in swaps}, {r for _, r in swaps}
    rest = [int(p) for p in left_p if p not in swapped_p]
    on_label = [p for p in rest if image.overlap.shape[1] and image.overlap[p].max() >= MATCH_IOU]
    return Outcome(matches, swaps, on_label, [p for p in rest if p not in on_label],
                   [int(r) for r in left_r if r not in swapped_r])


def confusion_matrix(images: list[ImageEvaluation], outcomes: list[Outcome], classes: tuple[str, ...]) -> np.ndarray:
    """Counts from each image's ``outcome``: rows are the true class, then "none"; columns the detected class, then
    "none".

    Matches fill the diagonal and swaps lie off it; duplicates and strays (detections on no free label) fill the
    "none" row, missed labels the "none" column. The thesis's FP is everything off the diagonal in the class
    columns, its FN everything off it in the class rows.
    """
    none = len(classes)
    matrix = np.zeros((none + 1, none + 1), dtype=int)
    for image, result in zip(images, outcomes, strict=True):
        truth, detected = image.truth_classes, image.classes
        for p, r in result.matches + result.swaps:
            matrix[classes.index(truth[r]), classes.index(detected[p])] += 1
        for p in result.duplicates + result.strays:
            matrix[none, classes.index(detected[p])] += 1
        for r in result.missed:
            matrix[classes.index(truth[r]), none] += 1
    return matrix


def confidence_sweep(images: list[ImageEvaluation], thresholds: np.ndarray | None = None) -> list[SweepPoint]:
    """Precision, recall and F1 at each confidence threshold."""
    thresholds = np.round(np.arange(0.05, 1.0, 0.05), 2) if thresholds is None else thresholds
    return [SweepPoint(float(t), *totals(images, float(t)).precision_recall()) for t in thresholds]


def best_threshold(sweep: list[SweepPoint]) -> float | None:
    """The threshold of the sweep's best F1, or None when every threshold counts the same (a front end whose
    detections all have one confidence, as the colour filter's do): then no threshold is better than another."""
    if len({round(point.f1, 9) for point in sweep}) == 1:
        return None
    return max(sweep, key=lambda point: point.f1).conf


def map_scores(images: list[ImageEvaluation], classes: tuple[str, ...]) -> MapScores | None:
    """Ultralytics' mAP50 and mAP50-95 over the images' IoU, mask or box (None for the colour filter's points)."""
    if not images or images[0].matching == "point":
        return None
    from ultralytics.utils.metrics import ap_per_class  # deferred: it loads torch, which counting does not need

    tp_rows, conf, pred_cls, target_cls = [], [], [], []
    for image in images:
        n = len(image.detections)
        tp = np.zeros((n, len(MAP_THRESHOLDS)), dtype=bool)
        for k, threshold in enumerate(MAP_THRESHOLDS):
            for p, _ in image.match(0.0, float(threshold)):
                tp[p, k] = True
        tp_rows.append(tp)
        conf.extend(image.scores.tolist())
        pred_cls.extend(classes.index(c) for c in image.classes)
        target_cls.extend(classes.index(c) for c in image.truth_classes)
    if not target_cls:
        return None
    ap = ap_per_class(np.concatenate(tp_rows), np.array(conf), np.array(pred_cls), np.array(target_cls))[5]
    return MapScores(float(ap[:, 0].mean()), float(ap.mean()))
