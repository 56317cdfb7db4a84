"""``poles pick``: the frames of a team's recording worth a person's labelling time.

Both front ends look at every frame: the accurate model (the teacher) and the robot front end (the one that must work
on the robot). A frame is worth labelling where they disagree: a pole the accurate model is sure of that the robot
does not report (a likely robot miss), a pole the robot reports that the accurate model does not see even below its
threshold (a likely robot false positive), a pole the two name differently, or a confidence just under either
threshold that the other front end does not back. The frames that disagree most are picked, spread over the
recording (a picked frame keeps its neighbours out), and written as a Roboflow-ready upload with the accurate model's
pre-labels, beside a contact sheet of why each was picked.

The recording is read twice (once to score every frame, once to write the picked ones), so a long video needs the
memory of one frame and a score per frame.
"""
from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from detector.console import show_progress
from detector.datasets.io import DATASET
from detector.formats import write_record
from detector.matching import box_iou
from detector.outputs import check_output_folder
from detector.prediction import detections_to_instances, draw_detections, frames_in, write_prelabels
from detector.preview import contact_sheet, draw_label
from detector.records import JsonRecord
from naoslam.perception.detections import Detection
from naoslam.perception.interface import PoleDetector
from naoslam.perception.loading import load_detector

#: How far below each front end's own threshold a detection counts as unsure (it would flip with a little change).
NEAR_THRESHOLD = 0.15
#: Boxes of one pole as the two front ends frame it (the robot's windows frame a pole more loosely than a mask).
SAME_POLE_IOU = 0.3
#: What each kind of disagreement adds to a frame's score: an unsure detection is half a likely error.
UNSURE_WEIGHT = 0.5
#: The contact sheet: tiles across, and each tile's width.
SHEET_COLUMNS, SHEET_TILE_WIDTH = 4, 480
#: The robot front end's boxes on the contact sheet (BGR): white, beside the accurate model's tinted masks.
ROBOT_BOX_BGR = (255, 255, 255)


@dataclass(frozen=True)
class FrameDisagreement(JsonRecord):
    """How much the two front ends disagree on one frame of the recording (``index`` in reading order)."""

    index: int
    name: str
    #: Poles the accurate model is sure of that the robot front end does not report.
    missed: int
    #: Poles the robot front end reports that the accurate model does not see, even below its threshold.
    extra: int
    #: Poles both report under different classes.
    renamed: int
    #: Detections just under a front end's threshold that the other front end does not report.
    unsure: int

    @property
    def score(self) -> float:
        return self.missed + self.extra + self.renamed + UNSURE_WEIGHT * self.unsure

    def why(self) -> str:
        """The reasons in words, for the contact sheet."""
        parts = [(self.missed, "robot misses"), (self.extra, "robot only"), (self.renamed, "classes differ"),
                 (self.unsure, "near a threshold")]
        return ", ".join(f"{count} {words}" for count, words in parts if count) or "they agree"


def frame_disagreement(index: int, name: str, accurate: list[Detection], accurate_conf: float,
                       robot: list[Detection], robot_conf: float) -> FrameDisagreement:
    """Compare one frame's detections of both front ends, each given down to ``NEAR_THRESHOLD`` below its own
    threshold (``accurate_conf``, ``robot_conf``); two detections are of one pole where their boxes overlap by
    ``SAME_POLE_IOU``."""
    accurate_sure = np.array([d.confidence >= accurate_conf for d in accurate], bool)
    robot_sure = np.array([d.confidence >= robot_conf for d in robot], bool)
    same = box_iou(_boxes(accurate), _boxes(robot)) >= SAME_POLE_IOU
    backed_by_robot = (same & robot_sure[None, :]).any(axis=1)
    backed_by_accurate = (same & accurate_sure[:, None]).any(axis=0)
    seen_by_accurate = same.any(axis=0)
    both_sure = same & accurate_sure[:, None] & robot_sure[None, :]
    renamed = sum(accurate[i].name != robot[j].name for i, j in zip(*np.nonzero(both_sure)))
    return FrameDisagreement(index, name, missed=int((accurate_sure & ~backed_by_robot).sum()),
                             extra=int((robot_sure & ~seen_by_accurate).sum()), renamed=int(renamed),
                             unsure=int((~accurate_sure & ~backed_by_robot).sum()
                                        + (~robot_sure & ~backed_by_accurate).sum()))


def spread_pick(frames: list[FrameDisagreement], count: int) -> list[FrameDisagreement]:
    """Up to ``count`` frames in reading order: those that disagree most first, none within a gap (the recording's
    length over twice the count) of one already picked, so one moment does not fill the pick; where too few frames
    disagree, the rest evenly over the frames left."""
    gap = max(1, len(frames) // (2 * count))
    picked: list[FrameDisagreement] = []
    for frame in sorted(frames, key=lambda f: (-f.score, f.index)):
        if len(picked) == count or frame.score == 0:
            break
        if all(abs(frame.index - other.index) >= gap for other in picked):
            picked.append(frame)
    chosen = {frame.index for frame in picked}
    rest = [frame for frame in frames if frame.index not in chosen]
    need = min(count - len(picked), len(rest))
    if need > 0:
        picked += [rest[i] for i in np.linspace(0, len(rest) - 1, need).round().astype(int)]
    return sorted(picked, key=lambda frame: frame.index)


@dataclass(frozen=True)
class PickResult(JsonRecord):
    """What ``poles pick`` did: the frames it compared, how many disagree at all, each front end's threshold, the
    frames it picked (in reading order) and where it wrote them."""

    frames: int
    disagreeing: int
    accurate_conf: float
    robot_conf: float
    picked: tuple[FrameDisagreement, ...]
    out: Path

    @property
    def sheet(self) -> Path:
        return self.out / "picked.png"


def pick_frames(source: Path, out: Path, count: int, teacher: str | Path = "shipped",
                robot: str | Path = "shipped-robot", fmt: str = "yolov8", force: bool = False,
                progress: bool = True) -> PickResult:
    """Compare both front ends over every frame of ``source`` (a folder of frames, subfolders too, or a video), and
    write the ``count`` frames worth labelling to ``out`` with the ``teacher``'s pre-labels, ``picked.json`` and
    ``picked.png`` (why each was picked)."""
    if count < 1:
        raise ValueError(f"--count {count}: pick at least one frame")
    total, _, frames = frames_in(source, subfolders=True)  # every frame decodes, before a model loads
    check_output_folder(out, force, (Path(source).resolve(),), DATASET)
    (accurate, accurate_conf), (robot_front, robot_conf) = _near_threshold(teacher), _near_threshold(robot)
    scored = [frame_disagreement(index, name, accurate(frame), accurate_conf, robot_front(frame), robot_conf)
              for index, (name, frame, _) in enumerate(show_progress(frames, "comparing", "frame", total=total,
                                                                     enabled=progress))]
    picked = spread_pick(scored, count)
    result = PickResult(len(scored), sum(frame.score > 0 for frame in scored), accurate_conf, robot_conf,
                        tuple(picked), Path(out).resolve())
    wanted = {frame.index: frame for frame in picked}
    tiles: list[tuple[np.ndarray, str]] = []

    def labelled() -> Iterator[tuple[str, np.ndarray, Path | None, list]]:
        _, _, again = frames_in(source, subfolders=True)
        for index, (name, frame, path) in enumerate(again):
            if index in wanted:
                sure = [d for d in accurate(frame) if d.confidence >= accurate_conf]
                tiles.append((_tile(frame, sure, robot_front(frame), robot_conf), f"{name}: {wanted[index].why()}"))
                yield name, frame, path, detections_to_instances(sure, frame.shape[:2])

    def beside(folder: Path) -> None:
        contact_sheet(tiles, folder / result.sheet.name, columns=SHEET_COLUMNS, tile_width=SHEET_TILE_WIDTH)
        write_record(folder / "picked.json", "pick", result.to_json())

    write_prelabels(out, labelled(), fmt, force, Path(source).resolve(), beside)
    return result


def _near_threshold(model: str | Path) -> tuple[PoleDetector, float]:
    """The model's front end, reporting down to ``NEAR_THRESHOLD`` under its own threshold, and that threshold."""
    detector = load_detector(model)
    threshold = detector.conf
    detector.conf = max(0.01, threshold - NEAR_THRESHOLD)
    return detector, threshold


def _tile(frame: np.ndarray, accurate: list[Detection], robot: list[Detection], robot_conf: float) -> np.ndarray:
    """The frame with the accurate model's sure poles tinted and labelled, and the robot's sure boxes in white."""
    tile = draw_detections(frame, accurate, [])
    for detection in robot:
        if detection.confidence >= robot_conf:
            x0, y0, x1, y1 = (int(round(v)) for v in detection.box)
            cv2.rectangle(tile, (x0, y0), (x1, y1), ROBOT_BOX_BGR, 2)
            draw_label(tile, f"robot {detection.name} {detection.confidence:.2f}", (x0, y1 + 14), ROBOT_BOX_BGR)
    return tile


def _boxes(detections: list[Detection]) -> np.ndarray:
    return np.array([d.box for d in detections], float).reshape(-1, 4)
