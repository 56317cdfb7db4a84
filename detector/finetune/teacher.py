"""A team's unlabelled frames labelled by the accurate model (the teacher) for ``poles finetune --unlabelled``.

The teacher keeps only what it is sure of: a frame is kept when each of its detections is either at least
``sure_conf`` (a pole, written as the teacher's outline) or under ``FLOOR_CONF`` (nothing); a frame with a detection
in between is left out, since its label would be a guess. A kept frame without a sure pole is a pole-free frame: the
teacher saw nothing there even at ``FLOOR_CONF``. With a ``checker`` (the robot model the frames will teach), a
frame is left out too where the checker's crop network names one of the teacher's sure poles another landmark: at a
venue's own light the two err on different poles, and a class both name is far more often right. Every
``TEST_EVERY``-th kept frame (spread over the recording) is held out as the test split, so a fine-tune on unlabelled
frames alone is still judged on frames it never trained on (against the teacher's labels: agreement with the
teacher, not truth).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from detector.console import show_progress
from detector.datasets.io import DatasetWriter
from detector.prediction import detections_to_instances, frames_in, jpeg_bytes
from detector.records import JsonRecord
from naoslam.perception.candidates import window_around_box
from naoslam.perception.detections import Detection
from naoslam.perception.loading import load_detector
from naoslam.perception.two_stage import CropDetector
from naoslam.shipped import DEFAULT_CONF

#: Below this confidence the teacher's detections count as nothing seen.
FLOOR_CONF = 0.1
#: The shipped accurate model's sure threshold: the lowest at which its precision reaches 95 % (95.0 %, recall
#: 92.9 %) on 400 rendered frames over real backdrops (`poles evaluate runs/table-sets/fresh-361 --model shipped`,
#: its sweep; at its operating 0.55: 93.4 %). Another teacher (a team's fine-tune) is sure at its own threshold.
SHIPPED_SURE_CONF = 0.7
#: Every so many kept frames one is held out as the test split.
TEST_EVERY = 7
#: Frames labelled before the teacher's speed sets how many of the rest it has time for (the first, warming the
#: models up, is not timed).
TIMED_FRAMES = 5


@dataclass(frozen=True)
class TeacherLabels(JsonRecord):
    """What the teacher made of the unlabelled frames: frames read, kept (with poles, and pole-free), left out as
    unsure (``disputed`` of them because the checker named a sure pole otherwise), poles labelled, held out as test,
    and the thresholds it used."""

    source: Path
    teacher: str
    frames: int
    #: Every so many frames were labelled, to keep to the seconds the teacher was given (1: every frame).
    stride: int
    kept: int
    pole_free: int
    unsure: int
    poles: int
    test: int
    sure_conf: float
    floor_conf: float
    disputed: int = 0


def teacher_labels(source: Path, out: Path, teacher: str, sure_conf: float | None, seconds: float,
                   checker: str | None = None, progress: bool = True) -> TeacherLabels:
    """Label the frames of ``source`` (a folder, subfolders too, or a video) with ``teacher`` into a YOLOv8 dataset
    at ``out`` (train and test splits), keeping only the frames it is sure of (at ``sure_conf``; None: the
    teacher's own threshold) and whose sure poles ``checker`` (a robot model, or None) names alike; returns what it
    kept. Once the first ``TIMED_FRAMES`` are labelled, every so many frames are labelled from then on, evenly over
    the recording, so the whole takes about ``seconds``."""
    total, _, frames = frames_in(source, subfolders=True)
    detector = load_detector(teacher, conf=FLOOR_CONF)
    student = CropDetector(checker) if checker is not None else None
    sure_conf = sure_conf if sure_conf is not None else detector.stored_conf or DEFAULT_CONF
    kept = pole_free = unsure = disputed = poles = test = looked = 0
    stride, began = 1, 0.0
    with DatasetWriter(out, force=True, protect=(Path(source).resolve(),)) as writer:
        for index, (name, frame, path) in enumerate(show_progress(frames, "teacher labelling", "frame", total=total,
                                                                  enabled=progress)):
            if index % stride:
                continue
            found = detector(frame)
            looked += 1
            if looked == 1:
                began = time.perf_counter()  # the first frame warms the models up: the pace is timed after it
            elif looked == TIMED_FRAMES:
                pace = (time.perf_counter() - began) / (looked - 1)
                stride = min(max(1, math.ceil(total * pace / seconds)), total)
            if any(d.confidence < sure_conf for d in found):
                unsure += 1
                continue
            if student is not None and names_otherwise(student, frame, found):
                unsure, disputed = unsure + 1, disputed + 1
                continue
            split = "test" if kept % TEST_EVERY == TEST_EVERY - 1 else "train"
            instances = detections_to_instances(found, frame.shape[:2])
            writer.add(split, name, path or jpeg_bytes(frame), instances)
            kept, test = kept + 1, test + (split == "test")
            pole_free += not instances
            poles += len(instances)
    return TeacherLabels(Path(source), str(teacher), total, stride, kept, pole_free, unsure, poles, test, sure_conf,
                         FLOOR_CONF, disputed)


def names_otherwise(student: CropDetector, frame: np.ndarray, found: list[Detection]) -> bool:
    """Whether the student's crop network names any of the teacher's poles (``found``) another landmark: its most
    likely landmark in the window the finder would draw around the pole's box."""
    if not found:
        return False
    windows = np.array([window_around_box(d.box, frame.shape[:2]) for d in found])
    named = student.run(frame, windows)[:, :len(student.classes)].argmax(axis=1)
    return any(student.classes[index] != d.name for index, d in zip(named, found))

