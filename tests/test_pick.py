"""``poles pick``: the frames where the robot front end and the accurate model disagree, spread over the recording."""
from __future__ import annotations

import hashlib
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from detector.cli import main
from detector.datasets import load_dataset
from detector.formats import read_record
from detector.picking import FrameDisagreement, frame_disagreement, spread_pick
from naoslam.landmarks import CLASSES
from naoslam.perception.detections import Detection


def _pole(name: str, confidence: float, x: float) -> Detection:
    """A box-only detection of a pole 20 px wide and 80 px tall at column ``x``."""
    box = (x, 100.0, x + 20.0, 180.0)
    return Detection(CLASSES.index(name), name, confidence, box, np.zeros((0, 0), bool), (0, 0), None, x + 10.0,
                     box_only=True)


def test_each_kind_of_disagreement_is_counted_once():
    """Thresholds 0.5 (accurate) and 0.6 (robot): a pole both see alike, one only the accurate model is sure of,
    one only the robot reports, one they name differently, and one just under the accurate model's threshold that
    the robot does not report."""
    accurate = [_pole("bp", 0.9, 0), _pole("gp", 0.8, 100), _pole("yp", 0.9, 300), _pole("pb", 0.4, 400)]
    robot = [_pole("bp", 0.7, 2), _pole("pg", 0.9, 200), _pole("py", 0.8, 302)]
    found = frame_disagreement(3, "f.jpg", accurate, 0.5, robot, 0.6)
    assert (found.missed, found.extra, found.renamed, found.unsure) == (1, 1, 1, 1)
    assert found.score == 3.5 and found.why() == "1 robot misses, 1 robot only, 1 classes differ, 1 near a threshold"
    agreeing = frame_disagreement(0, "g.jpg", accurate[:1], 0.5, robot[:1], 0.6)
    assert agreeing.score == 0 and agreeing.why() == "they agree"
    under_robot = frame_disagreement(0, "h.jpg", accurate[:1], 0.5, [_pole("bp", 0.5, 2)], 0.6)
    assert (under_robot.missed, under_robot.unsure) == (1, 0)  # the robot's weak box is backed by the sure pole


def _scored(scores: list[float]) -> list[FrameDisagreement]:
    return [FrameDisagreement(index, f"{index:03d}.jpg", int(score), 0, 0, 0) for index, score in enumerate(scores)]


def test_the_pick_takes_the_frames_that_disagree_most_and_not_one_moment_twice():
    """Frames 10-12 disagree most, 30 and 50 less; two picks from 60 frames keep 15 frames apart, so the second is
    30, not 11; five picks with three disagreeing moments fill the rest evenly."""
    scores = [0.0] * 60
    scores[10:13] = [5, 6, 5]
    scores[30], scores[50] = 3, 2
    assert [frame.index for frame in spread_pick(_scored(scores), 2)] == [11, 30]
    five = [frame.index for frame in spread_pick(_scored(scores), 5)]
    assert five[:1] == [0] and {11, 30, 50} <= set(five) and len(set(five)) == 5
    assert len(spread_pick(_scored([1.0, 2.0]), 5)) == 2


@pytest.fixture(scope="module")
def recording(synth_dataset, tmp_path_factory) -> Path:
    """A recording of eight frames: the rendered test frames and plain floors between them."""
    folder = tmp_path_factory.mktemp("recording") / "walk"
    folder.mkdir()
    frames = sorted((synth_dataset / "test" / "images").glob("*.jpg"))[:4]
    for index, image in enumerate(frames):
        shutil.copy(image, folder / f"{2 * index:03d}.jpg")
        cv2.imwrite(str(folder / f"{2 * index + 1:03d}.jpg"), np.full((480, 640, 3), (60, 130, 50), np.uint8))
    return folder


def _digest(folder: Path) -> str:
    files = sorted(path for path in folder.rglob("*") if path.is_file())
    return hashlib.sha256(b"".join(path.read_bytes() for path in files)).hexdigest()


def test_pick_writes_a_roboflow_upload_of_the_picked_frames_with_why(recording, tmp_path, capsys):
    before = _digest(recording)
    out = tmp_path / "upload"
    assert main(["pick", str(recording), "--out", str(out), "--count", "3", "--robot", "colour-filter"]) == 0
    assert "compared 8 frames" in capsys.readouterr().out
    record = read_record(out / "picked.json", "pick")
    picked = [frame["name"] for frame in record["picked"]]
    assert len(picked) == 3 and picked == sorted(picked)
    assert sorted(sample.image.name for sample in load_dataset(out).samples) == picked
    if record["disagreeing"] >= 3:  # every picked frame is one where they disagree
        assert all(frame["missed"] + frame["extra"] + frame["renamed"] + frame["unsure"] for frame in record["picked"])
    assert cv2.imread(str(out / "picked.png")) is not None
    assert _digest(recording) == before


def test_pick_refuses_what_it_cannot_use_in_one_line(recording, tmp_path, capsys):
    empty = tmp_path / "empty"
    empty.mkdir()
    for arguments, words in ((["pick", str(empty)], "no images"), (["pick", str(recording), "--count", "0"],
                                                                   "pick at least one frame"),
                             (["pick", str(tmp_path / "walk.mp4")], "not a readable video")):
        assert main([*arguments, "--out", str(tmp_path / "out")]) == 2
        error = capsys.readouterr().err
        assert words in error and "Traceback" not in error and len(error.strip().splitlines()) == 1, error
    assert not (tmp_path / "out").exists()
