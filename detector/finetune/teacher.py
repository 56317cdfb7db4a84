"""A team's unlabelled frames labelled by the accurate model (the teacher) for ``poles finetune --unlabelled``.

The teacher keeps only what it is sure of: a frame is kept when each of its detections is either at least
``sure_conf`` (a pole, written as the teacher's outline) or under ``FLOOR_CONF`` (nothing); a frame with a detection
in between is left out, since its label would be a guess. A kept frame without a sure pole is a pole-free frame: the
teacher saw nothing there even at ``FLOOR_CONF``. Every ``TEST_EVERY``-th kept frame (spread over the recording) is
held out as the test split, so a fine-tune on unlabelled frames alone is still judged on frames it never trained on
(against the teacher's labels: agreement with the teacher, not truth).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

from detector.console import show_progress
from detector.datasets.io import DatasetWriter
from detector.prediction import detections_to_instances, frames_in, jpeg_bytes
from detector.records import JsonRecord
from naoslam.perception.loading import load_detector
from naoslam.shipped import DEFAULT_CONF

#: Below this confidence the teacher's detections count as nothing seen.
FLOOR_CONF = 0.1
#: The shipped accurate model's sure threshold: the lowest at which its precision reaches 95 % (95.0 %, recall
#: 92.9 %) on 400 rendered frames over real backdrops (`poles evaluate runs/table-sets/fresh-361 --model shipped`,
#: its sweep; at its operating 0.55: 93.4 %). Another teacher (a team's fine-tune) is sure at its own threshold.
SHIPPED_SURE_CONF = 0.7
#: Every so many kept frames one is held out as the test split.
TEST_EVERY = 7
#: Frames labelled before the teacher's speed sets how many of the rest it has time for.
TIMED_FRAMES = 5


@dataclass(frozen=True)
class TeacherLabels(JsonRecord):
    """What the teacher made of the unlabelled frames: frames read, kept (with poles, and pole-free), left out as
    unsure, poles labelled, held out as test, and the thresholds it used."""

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


def teacher_labels(source: Path, out: Path, teacher: str, sure_conf: float | None, seconds: float,
                   progress: bool = True) -> TeacherLabels:
    """Label the frames of ``source`` (a folder, subfolders too, or a video) with ``teacher`` into a YOLOv8 dataset
    at ``out`` (train and test splits), keeping only the frames it is sure of (at ``sure_conf``; None: the
    teacher's own threshold); returns what it kept. Once the first
    ``TIMED_FRAMES`` are labelled, every so many frames are labelled from then on, evenly over the recording, so
    the whole takes about ``seconds``."""
    total, _, frames = frames_in(source, subfolders=True)
    detector = load_detector(teacher, conf=FLOOR_CONF)
    sure_conf = sure_conf if sure_conf is not None else detector.stored_conf or DEFAULT_CONF
    kept = pole_free = unsure = poles = test = looked = 0
    stride, began = 1, time.perf_counter()
    with DatasetWriter(out, force=True, protect=(Path(source).resolve(),)) as writer:
        for index, (name, frame, path) in enumerate(show_progress(frames, "teacher labelling", "frame", total=total,
                                                                  enabled=progress)):
            if index % stride:
                continue
            found = detector(frame)
            looked += 1
            if looked == TIMED_FRAMES:
                stride = min(max(1, math.ceil(total * (time.perf_counter() - began) / looked / seconds)), total)
            if any(d.confidence < sure_conf for d in found):
                unsure += 1
                continue
            split = "test" if kept % TEST_EVERY == TEST_EVERY - 1 else "train"
            instances = detections_to_instances(found, frame.shape[:2])
            writer.add(split, name, path or jpeg_bytes(frame), instances)
            kept, test = kept + 1, test + (split == "test")
            pole_free += not instances
            poles += len(instances)
    return TeacherLabels(Path(source), str(teacher), total, stride, kept, pole_free, unsure, poles, test, sure_conf,
                         FLOOR_CONF)

