"""Training crops from an annotated dataset: every candidate the robot's finder proposes, named by the labelled pole
it covers (or as no pole), plus windows drawn around every labelled pole as the finder would draw them, jittered.

A candidate is a positive when its window holds at least ``MIN_COVERAGE`` of a pole's box and the pole fills
between ``MIN_FILL`` and ``MAX_FILL`` of the window's height; a negative when it holds under ``NEGATIVE_COVERAGE`` of
every pole; anything between is left out, so the network is never taught two answers for one sight.
"""
from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from detector.console import show_progress
from detector.datasets.model import Dataset, Sample
from detector.datasets.truth import load_camera_poses
from naoslam.camera import CameraPose, PinholeCamera
from naoslam.perception.candidates import (WINDOW_ABOVE_JUNCTION, WINDOW_HEIGHT, CandidateFinder, cut_by_frame,
                                window_around_box, window_at_junction)
from naoslam.perception.crops import Window, crop_window, to_crop
from naoslam.ground import GroundView
from naoslam.landmarks import CLASSES

#: Class index of "no pole" (after the six landmarks).
NO_POLE = len(CLASSES)
MIN_COVERAGE, NEGATIVE_COVERAGE = 0.7, 0.2
MIN_FILL, MAX_FILL = 0.3, 1.3
#: Windows drawn around each labelled pole, and how much they move (band heights) and scale (log s.d.).
JITTERED_WINDOWS = 2
JITTER_SHIFT, JITTER_SCALE = 0.2, 0.12


@dataclass
class CropSet:
    """Crops (N, H, W, 3 BGR uint8), their class (0-5 a landmark, 6 no pole) and pole box (N, 4, normalised to the
    crop; NaN for no pole)."""

    crops: np.ndarray
    classes: np.ndarray
    boxes: np.ndarray

    def __len__(self) -> int:
        return len(self.classes)

    @classmethod
    def empty(cls, size_wh: tuple[int, int]) -> "CropSet":
        """A set of no crops of this size (width, height)."""
        return cls(np.zeros((0, size_wh[1], size_wh[0], 3), np.uint8), np.zeros(0, np.int64),
                   np.zeros((0, 4), np.float32))

    @classmethod
    def concatenate(cls, sets: list["CropSet"]) -> "CropSet":
        return cls(np.concatenate([s.crops for s in sets]), np.concatenate([s.classes for s in sets]),
                   np.concatenate([s.boxes for s in sets]))

    def save(self, path: Path) -> None:
        np.savez(path, crops=self.crops, classes=self.classes, boxes=self.boxes)

    @classmethod
    def load(cls, path: Path) -> "CropSet":
        data = np.load(path)
        return cls(data["crops"], data["classes"], data["boxes"])


def coverage(window: Window, box: Window) -> float:
    """The share of ``box``'s area inside ``window``."""
    width = min(window[2], box[2]) - max(window[0], box[0])
    height = min(window[3], box[3]) - max(window[1], box[1])
    area = (box[2] - box[0]) * (box[3] - box[1])
    return max(width, 0.0) * max(height, 0.0) / area if area > 0 else 0.0


def pole_for(window: Window, boxes: list[Window], frame_hw: tuple[int, int]) -> int | None:
    """The pole a window frames (index into ``boxes``), -1 when it shows none, None when it is unclear. It frames a
    pole when it holds ``MIN_COVERAGE`` of the pole's box and the pole fills ``MIN_FILL`` to ``MAX_FILL`` of its
    height (a pole cut by the frame's top or bottom may fill less)."""
    shares = [coverage(window, box) for box in boxes]
    height = window[3] - window[1]

    def fits(i: int) -> bool:
        fill = (boxes[i][3] - boxes[i][1]) / height
        return shares[i] >= MIN_COVERAGE and fill <= MAX_FILL and (fill >= MIN_FILL or cut_by_frame(boxes[i], frame_hw))

    framed = [i for i in range(len(boxes)) if fits(i)]
    if framed:
        return max(framed, key=shares.__getitem__)
    return -1 if max(shares, default=0.0) < NEGATIVE_COVERAGE else None


def jittered(window: Window, rng: np.random.Generator) -> Window:
    """A window moved and scaled at random, as the finder's anchors vary."""
    x0, y0, x1, y1 = window
    band = (y1 - y0) / WINDOW_HEIGHT
    centre = (x0 + x1) / 2 + rng.normal(0.0, JITTER_SHIFT) * band
    junction = y0 + WINDOW_ABOVE_JUNCTION * band + rng.normal(0.0, JITTER_SHIFT) * band
    return window_at_junction(centre, junction, band * float(np.exp(rng.normal(0.0, JITTER_SCALE))))


def ground_view(pose: CameraPose | None, frame_hw: tuple[int, int]) -> GroundView | None:
    """The ground view of a frame taken at the camera ``pose`` (None without one)."""
    return GroundView(PinholeCamera(frame_hw[1], frame_hw[0]), pose) if pose is not None else None


def label_boxes(sample: Sample, width: int, height: int) -> list[Window]:
    """Each labelled pole's box in frame pixels (its polygon's extent, clipped to the frame)."""
    boxes = []
    for instance in sample.instances:
        points = instance.pixels(width, height)
        x0, y0 = np.clip(points.min(axis=0), 0, [width, height])
        x1, y1 = np.clip(points.max(axis=0), 0, [width, height])
        boxes.append((float(x0), float(y0), float(x1), float(y1)))
    return boxes


def crops_of_frame(frame: np.ndarray, sample: Sample, view: GroundView | None, finder: CandidateFinder,
                   size_wh: tuple[int, int], rng: np.random.Generator, jitter: int = JITTERED_WINDOWS) -> CropSet:
    """The training crops of one frame: its candidates (positives and negatives) with the camera's pose where the
    frame has one and without it (a team's frames, the robot before its pose is known), and jittered finder windows
    around each labelled pole."""
    height, width = frame.shape[:2]
    boxes = label_boxes(sample, width, height)
    windows, targets = labelled_windows([c.window for c in frame_candidates(frame, view, finder)], boxes,
                                        (height, width))
    for pole, box in enumerate(boxes):
        for _ in range(jitter):
            windows.append(jittered(window_around_box(box, (height, width)), rng))
            targets.append(pole)
    return crops_at(frame, windows, targets, boxes, [instance.cls for instance in sample.instances], size_wh)


def frame_candidates(frame: np.ndarray, view: GroundView | None, finder: CandidateFinder) -> list:
    """The finder's candidates in a frame with the camera's pose where there is one and without it, each window once."""
    return _distinct(finder(frame, view) + (finder(frame) if view is not None else []))


def labelled_windows(windows: list[Window], boxes: list[Window],
                     frame_hw: tuple[int, int]) -> tuple[list[Window], list[int]]:
    """The windows that clearly frame a pole or show none (:func:`pole_for`), with the pole each frames (-1: none)."""
    kept, targets = [], []
    for window in windows:
        pole = pole_for(window, boxes, frame_hw)
        if pole is not None:
            kept.append(window)
            targets.append(pole)
    return kept, targets


def crops_at(frame: np.ndarray, windows: list[Window], targets: list[int], boxes: list[Window], classes: list[str],
             size_wh: tuple[int, int]) -> CropSet:
    """The windows cut from the frame, each named by its target pole (``classes``, ``boxes``) or as no pole (-1)."""
    if not windows:
        return CropSet.empty(size_wh)
    crops = np.stack([crop_window(frame, w, size_wh) for w in windows])
    class_ids = np.array([NO_POLE if t < 0 else CLASSES.index(classes[t]) for t in targets], np.int64)
    crop_boxes = np.array([np.full(4, np.nan) if t < 0 else to_crop(boxes[t], w) for w, t in zip(windows, targets)],
                          np.float32).reshape(-1, 4)
    return CropSet(crops, class_ids, crop_boxes)


def _distinct(candidates: list) -> list:
    """The candidates without repeats (the same window found with and without the pose)."""
    seen, out = set(), []
    for candidate in candidates:
        key = tuple(round(v) for v in candidate.window)
        if key not in seen:
            seen.add(key)
            out.append(candidate)
    return out


def annotated_frames(dataset: Dataset, splits: tuple[str, ...], label: str,
                     progress: bool = True) -> Iterator[tuple[Sample, np.ndarray, GroundView | None]]:
    """Every frame of ``splits`` of a dataset read through the intake, with its ground view where
    ``annotations.json`` records the camera's pose (the finder then searches the ground band, as on the robot)."""
    poses = load_camera_poses(dataset)
    samples = [s for split in splits for s in dataset.split(split)]
    for sample in show_progress(samples, f"{label} {Path(dataset.root).name}", "img", enabled=progress):
        frame = cv2.imread(str(sample.image))  # the intake decoded each one; a truncated JPEG reads grey below
        yield sample, frame, ground_view(poses.get(sample.image.name), frame.shape[:2])


def crops_of_dataset(dataset: Dataset, splits: tuple[str, ...], size_wh: tuple[int, int], seed: int = 0,
                     jitter: int = JITTERED_WINDOWS, progress: bool = True) -> CropSet:
    """The training crops (:func:`crops_of_frame`) of every frame of ``splits`` of a dataset."""
    finder = CandidateFinder()
    sets = [crops_of_frame(frame, sample, view, finder, size_wh, np.random.default_rng([seed, index]), jitter)
            for index, (sample, frame, view) in enumerate(annotated_frames(dataset, splits, "cropping", progress))]
    return CropSet.concatenate(sets) if sets else CropSet.empty(size_wh)
