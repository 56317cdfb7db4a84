"""Does an exported model give the same answers? Detections of two predictors on the same frames, compared."""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from detector.matching import box_iou, greedy_match
from detector.records import JsonRecord
from naoslam.perception.detections import Detection
from naoslam.perception.yolo import LandmarkDetector


def frontend_predict(model: Path, frames: list[np.ndarray], conf: float,
                     input_hw: tuple[int, int] | None = None) -> list[list[Detection]]:
    """The naoslam front end's detections on the same frames (at ``input_hw``, default the model's own)."""
    detector = LandmarkDetector(model, conf=conf, classes=None)
    found = []
    for frame in frames:
        blob, box = detector.prepare(frame, input_hw)
        found.append(detector.decode(detector.forward(blob), box))
    return found


@dataclass(frozen=True)
class Tolerance:
    """Limits an agreement must meet. ``margin``: detections within it of the threshold may come and go."""

    min_box_iou: float
    min_mean_mask_iou: float
    max_score_diff: float
    max_unmatched_fraction: float
    max_class_change_fraction: float
    margin: float = 0.05


#: Same network, same runtime precision: only float rounding may differ.
FP32_TOLERANCE = Tolerance(min_box_iou=0.99, min_mean_mask_iou=0.95, max_score_diff=0.01, max_unmatched_fraction=0.0,
                           max_class_change_fraction=0.0)
#: INT8 against FP32: a gross-failure guard, the figures themselves are reported.
INT8_TOLERANCE = Tolerance(min_box_iou=0.5, min_mean_mask_iou=0.7, max_score_diff=0.25, max_unmatched_fraction=0.2,
                           max_class_change_fraction=0.1, margin=0.1)


@dataclass(frozen=True)
class Agreement(JsonRecord):
    """How two predictors' detections on the same frames compare (matched one-to-one by box IoU >= 0.5)."""

    frames: int
    reference: int
    candidate: int
    matched: int
    unmatched_confident: int
    class_mismatches: int
    box_iou_min: float
    box_iou_mean: float
    mask_iou_min: float
    mask_iou_mean: float
    score_diff_max: float

    def problems(self, tolerance: Tolerance) -> list[str]:
        """What is beyond ``tolerance`` (empty when the two agree)."""
        out = []
        confident = max(self.reference, self.candidate, 1)
        if self.unmatched_confident / confident > tolerance.max_unmatched_fraction:
            out.append(f"{self.unmatched_confident} confident detection(s) have no counterpart")
        if self.class_mismatches > tolerance.max_class_change_fraction * self.matched:
            out.append(f"{self.class_mismatches} matched detection(s) change class")
        if self.matched and self.box_iou_min < tolerance.min_box_iou:
            out.append(f"box IoU down to {self.box_iou_min:.3f} (< {tolerance.min_box_iou})")
        if self.matched and self.mask_iou_mean < tolerance.min_mean_mask_iou:
            out.append(f"mean mask IoU {self.mask_iou_mean:.3f} (< {tolerance.min_mean_mask_iou})")
        if self.matched and self.score_diff_max > tolerance.max_score_diff:
            out.append(f"scores differ by up to {self.score_diff_max:.3f} (> {tolerance.max_score_diff})")
        return out


def compare(reference: list[list[Detection]], candidate: list[list[Detection]], conf: float,
            margin: float = 0.05) -> Agreement:
    """Match ``candidate`` to ``reference`` frame by frame; unmatched detections scoring over conf + margin count."""
    box_ious, mask_ious, score_diffs = [], [], []
    mismatches = unmatched = 0
    for ref, cand in zip(reference, candidate, strict=True):
        ious = box_iou(_boxes(cand), _boxes(ref))
        pairs = greedy_match(ious, np.array([d.confidence for d in cand]), 0.5)
        for c, r in pairs:
            box_ious.append(ious[c, r])
            mask_ious.append(cand[c].mask_iou(ref[r]))
            score_diffs.append(abs(cand[c].confidence - ref[r].confidence))
            mismatches += int(cand[c].class_id != ref[r].class_id)
        matched_c, matched_r = {c for c, _ in pairs}, {r for _, r in pairs}
        unmatched += sum(1 for i, d in enumerate(cand) if i not in matched_c and d.confidence > conf + margin)
        unmatched += sum(1 for i, d in enumerate(ref) if i not in matched_r and d.confidence > conf + margin)

    def stat(values: list[float], fn, empty: float) -> float:
        return float(fn(values)) if values else empty

    return Agreement(len(reference), sum(map(len, reference)), sum(map(len, candidate)),
                     len(box_ious), unmatched, mismatches, stat(box_ious, np.min, 1.0), stat(box_ious, np.mean, 1.0),
                     stat(mask_ious, np.min, 1.0), stat(mask_ious, np.mean, 1.0), stat(score_diffs, np.max, 0.0))


def _boxes(detections: list[Detection]) -> np.ndarray:
    """The detections' xyxy boxes as an (N, 4) array."""
    return np.array([d.box for d in detections], dtype=float).reshape(-1, 4)


def median_latency_ms(models: dict[str, Path], frames: list[np.ndarray], repeats: int = 3) -> dict[str, float]:
    """Median front-end time per frame (ms) of each model, runs interleaved so the machine's state is shared."""
    detectors = {name: LandmarkDetector(path, classes=None) for name, path in models.items()}
    times: dict[str, list[float]] = {name: [] for name in models}
    for detector in detectors.values():
        detector(frames[0])  # warm-up
    for _ in range(repeats):
        for frame in frames:
            for name, detector in detectors.items():
                start = time.perf_counter()
                detector(frame)
                times[name].append((time.perf_counter() - start) * 1000)
    return {name: float(np.median(values)) for name, values in times.items()}
