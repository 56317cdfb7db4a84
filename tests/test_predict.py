"""`poles predict`: pre-labels that check reads clean and that round-trip, overlay videos frame for frame."""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from detector.cli import main
from detector.datasets import load_dataset
from detector.synth.render import render_scene
from detector.synth.scene import calibration_scene
from naoslam.camera import PinholeCamera

CODES = ("bp", "gp", "yp", "pb", "pg", "py")


@pytest.fixture(scope="module")
def frames(tmp_path_factory) -> Path:
    """Six rendered 640x480 frames with one pole each, and one frame with none."""
    folder = tmp_path_factory.mktemp("frames")
    camera = PinholeCamera(640, 480)
    for index, code in enumerate(CODES):
        scene = calibration_scene(np.random.default_rng(index), camera, code, 1.0 + 0.5 * index, 10.0 - 4 * index)
        image = (render_scene(scene).image * 255 + 0.5).astype(np.uint8)
        cv2.imwrite(str(folder / f"{index:02d}_{code}.jpg"), cv2.cvtColor(image, cv2.COLOR_RGB2BGR))
    cv2.imwrite(str(folder / "99_empty.jpg"), np.full((480, 640, 3), 90, np.uint8))
    return folder


def classes_by_image(data: Path) -> dict[str, list[str]]:
    return {s.image.stem: sorted(i.cls for i in s.instances) for s in load_dataset(data).samples if s.image}


@pytest.mark.parametrize("fmt", ["yolov8", "coco"])
def test_prelabels_check_clean_and_round_trip(fmt, frames, tmp_path):
    out = tmp_path / "prelabels"
    assert main(["predict", "--images", str(frames), "--out", str(out), "--format", fmt]) == 0
    assert main(["check", str(out)]) == 0
    found = classes_by_image(out)
    assert found["99_empty"] == []
    right = sum(found[f"{i:02d}_{code}"] == [code] for i, code in enumerate(CODES))
    assert right >= 5, found
    assert main(["convert", str(out), "--out", str(tmp_path / "converted")]) == 0
    assert classes_by_image(tmp_path / "converted") == found


def test_prelabel_reads_subfolders_and_names_each_frame_by_its_path(frames, tmp_path):
    """A student's frames come in a folder per walk; none may be left out without a word."""
    walks = tmp_path / "walks"
    for walk, names in (("walk1", ["00_bp.jpg", "99_empty.jpg"]), ("walk2", ["01_gp.jpg"])):
        (walks / walk).mkdir(parents=True)
        for name in names:
            (walks / walk / name).write_bytes((frames / name).read_bytes())
    (walks / "03_pb.jpg").write_bytes((frames / "03_pb.jpg").read_bytes())
    assert main(["predict", "--images", str(walks), "--out", str(tmp_path / "out")]) == 0
    found = classes_by_image(tmp_path / "out")
    assert set(found) == {"03_pb", "walk1_00_bp", "walk1_99_empty", "walk2_01_gp"}
    assert (tmp_path / "out" / "train" / "images" / "walk1_00_bp.jpg").read_bytes() == \
        (frames / "00_bp.jpg").read_bytes()


def test_prelabel_refuses_two_frames_that_would_get_one_name(frames, tmp_path, capsys):
    walks = tmp_path / "walks"
    (walks / "a").mkdir(parents=True)
    (walks / "a" / "b.jpg").write_bytes((frames / "00_bp.jpg").read_bytes())
    (walks / "a_b.jpg").write_bytes((frames / "00_bp.jpg").read_bytes())
    assert main(["predict", "--images", str(walks), "--out", str(tmp_path / "out")]) == 2
    assert "would both be named a_b.jpg - rename one" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_prelabel_refuses_an_output_inside_the_frames(frames, capsys):
    assert main(["predict", "--images", str(frames), "--out", str(frames / "labels")]) == 2
    assert "overlaps the input" in capsys.readouterr().err
    assert not (frames / "labels").exists()


@pytest.fixture
def model_calls(monkeypatch) -> list[int]:
    """Counts the frames the pole model is run on."""
    from naoslam.perception.yolo import LandmarkDetector

    calls: list[int] = []
    run = LandmarkDetector.__call__
    monkeypatch.setattr(LandmarkDetector, "__call__", lambda self, frame: calls.append(1) or run(self, frame))
    return calls


@pytest.mark.parametrize("command", [["--images", "{frames}", "--out", "{out}"],
                                     ["--images", "{frames}", "--out", "{out}", "--format", "coco"],
                                     ["--video", "{frames}", "--out", "{out}.mp4"]])
def test_a_bad_frame_is_refused_before_the_model_runs(command, frames, tmp_path, model_calls, capsys):
    folder = tmp_path / "frames"
    folder.mkdir()
    for path in frames.glob("*.jpg"):
        (folder / path.name).write_bytes(path.read_bytes())
    (folder / "50_cut.jpg").write_bytes(b"\xff\xd8\xff")  # the last frame a robot wrote before it powered off
    (folder / "51_note.png").write_text("not an image")
    args = [a.format(frames=folder, out=tmp_path / "out") for a in command]
    assert main(["predict", *args]) == 2
    assert f"{folder / '50_cut.jpg'} (and 1 more): cannot be decoded" in capsys.readouterr().err
    assert model_calls == []
    assert list(tmp_path.iterdir()) == [folder]



def test_a_frame_cut_short_that_opencv_would_read_grey_is_refused(frames, tmp_path, model_calls, capsys):
    """A robot that powers off while writing leaves most of a JPEG: ``cv2.imread`` returns it, its bottom grey."""
    folder = tmp_path / "frames"
    folder.mkdir()
    data = (frames / "02_yp.jpg").read_bytes()
    (folder / "02_yp.jpg").write_bytes(data[: len(data) * 9 // 10])
    assert cv2.imread(str(folder / "02_yp.jpg")) is not None
    (folder / "03_pb.jpg").write_bytes((frames / "03_pb.jpg").read_bytes() + bytes(64))  # a capture buffer's padding
    assert main(["predict", "--images", str(folder), "--out", str(tmp_path / "out")]) == 2
    assert f"{folder / '02_yp.jpg'}: cannot be decoded whole (a truncated JPEG" in capsys.readouterr().err
    assert model_calls == []
    (folder / "02_yp.jpg").unlink()
    assert main(["predict", "--images", str(folder), "--out", str(tmp_path / "out")]) == 0
    assert set(classes_by_image(tmp_path / "out")) == {"03_pb"}

def test_prelabel_refuses_an_existing_output_before_the_model_runs(frames, tmp_path, model_calls, capsys):
    out = tmp_path / "prelabels"
    out.mkdir()
    (out / "yesterday.txt").write_text("the last batch's notes")
    assert main(["predict", "--images", str(frames), "--out", str(out)]) == 2
    assert "--force" in capsys.readouterr().err
    assert model_calls == []


def test_overlay_video_has_every_frame_at_the_input_size(frames, tmp_path):
    video = tmp_path / "run.mp4"
    assert main(["predict", "--video", str(frames), "--out", str(video)]) == 0
    capture = cv2.VideoCapture(str(video))
    count = 0
    while True:
        ok, frame = capture.read()
        if not ok:
            break
        assert frame.shape == (480, 640, 3)
        count += 1
    assert count == len(list(frames.glob("*.jpg")))
    assert cv2.imread(str(video.with_suffix(".png"))) is not None
    again = tmp_path / "again.mp4"
    assert main(["predict", "--video", str(video), "--out", str(again)]) == 0  # a video as the input
    assert int(cv2.VideoCapture(str(again)).get(cv2.CAP_PROP_FRAME_COUNT)) == count


def test_an_overlay_video_of_frames_too_small_to_show_a_pole_is_refused_for_its_frames(tmp_path, capsys):
    frames = tmp_path / "tiny"
    frames.mkdir()
    for index in range(3):
        cv2.imwrite(str(frames / f"{index:03d}.png"), np.full((1, 1, 3), 128, np.uint8))
    assert main(["predict", "--video", str(frames), "--out", str(tmp_path / "out.mp4"),
                 "--model", "shipped-robot"]) == 2
    message = capsys.readouterr().err
    assert "its frames are 1x1, too small to show a pole (at least 16 px a side)" in message, message
    assert sorted(path.name for path in tmp_path.iterdir()) == ["tiny"]


def test_prelabel_and_video_on_real_frames(real_poles, tmp_path):
    images = real_poles / "test" / "images"
    assert main(["predict", "--images", str(images), "--out", str(tmp_path / "pre")]) == 0
    assert main(["check", str(tmp_path / "pre")]) == 0
    assert len(load_dataset(tmp_path / "pre").samples) == len(list(images.glob("*.jpg")))
    assert main(["predict", "--video", str(images), "--out", str(tmp_path / "real.mp4")]) == 0
    assert int(cv2.VideoCapture(str(tmp_path / "real.mp4")).get(cv2.CAP_PROP_FRAME_COUNT)) == 14


def test_overlay_video_at_a_smaller_input_draws_no_range_the_calibration_cannot_give(frames, tmp_path, capsys):
    from detector.prediction import overlay_video

    own = overlay_video(frames, tmp_path / "own.mp4", progress=False)
    small = overlay_video(frames, tmp_path / "small.mp4", progress=False, input_width=320)
    assert (own.ranges, small.ranges) == (True, False)  # the shipped calibration is the 640 px one
    assert main(["predict", "--video", str(frames), "--out", str(tmp_path / "cli.mp4"), "--imgsz", "320"]) == 0
    assert "no ranges drawn" in capsys.readouterr().out
    assert main(["predict", "--images", str(frames), "--out", str(tmp_path / "labels"), "--imgsz", "320"]) == 2
    assert "--imgsz is for --video" in capsys.readouterr().err and not (tmp_path / "labels").exists()
