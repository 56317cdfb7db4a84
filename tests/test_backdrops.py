"""Poles drawn over real frames: labels stay exact, the frame is untouched away from the objects, bad folders named."""
from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from detector.cli import main
from detector.datasets.io import load_dataset
from detector.datasets.polygons import polygon_to_mask
from detector.synth.backdrops import (BACKLIGHT_SHARE, FEATHER_REACH_PX, RENDER_MAX_WIDTH, RENDER_MIN_WIDTH,
                                      composite, frame_cast, load_backdrop, sample_look, scan_backdrops)
from detector.synth.generate import SynthJob, generate_dataset
from detector.synth.render import render_scene
from detector.synth.scene import SceneConfig, sample_scene
from naoslam.camera import PinholeCamera


def _write_frame(path: Path, width: int, height: int, seed: int) -> Path:
    """A textured 'room' frame: smooth gradients plus noise, like a photo without poles."""
    rng = np.random.default_rng(seed)
    ramp = np.linspace(0, 1, width)[None, :, None] * rng.uniform(40, 120, 3) + rng.uniform(40, 120, 3)
    image = np.clip(ramp + rng.normal(0, 12, (height, width, 3)), 0, 255).astype(np.uint8)
    cv2.imwrite(str(path), image)
    return path


@pytest.fixture
def backdrop_folder(tmp_path) -> Path:
    folder = tmp_path / "backgrounds"
    (folder / "office").mkdir(parents=True)
    _write_frame(folder / "field.jpg", 640, 480, 1)
    _write_frame(folder / "office" / "small.png", 320, 240, 2)
    (folder / "README.md").write_text("frames without poles\n")
    return folder


def _far_from(mask: np.ndarray, reach: int) -> np.ndarray:
    """Pixels more than ``reach`` px (chessboard distance) from every True pixel of ``mask``."""
    return ~cv2.dilate(mask.astype(np.uint8), np.ones((2 * reach + 1,) * 2, np.uint8)).astype(bool)


def test_scan_finds_images_in_subfolders_and_ignores_other_files(backdrop_folder):
    assert [p.name for p in scan_backdrops(backdrop_folder)] == ["field.jpg", "small.png"]


def test_small_frames_are_upscaled_to_the_detector_width(backdrop_folder):
    image = load_backdrop(backdrop_folder / "office" / "small.png")
    assert image.shape == (480, RENDER_MIN_WIDTH, 3) and image.dtype == np.float32


def test_photographs_larger_than_a_robot_frame_are_downscaled_to_it(tmp_path):
    photo = load_backdrop(_write_frame(tmp_path / "phone.jpg", 4032, 3024, 3))
    assert photo.shape == (960, RENDER_MAX_WIDTH, 3)
    assert load_backdrop(_write_frame(tmp_path / "nao.jpg", 1280, 960, 4)).shape == (960, 1280, 3)


def test_composite_changes_only_the_objects_and_their_soft_edges():
    rng = np.random.default_rng(0)
    backdrop = rng.uniform(0, 1, (120, 160, 3)).astype(np.float32)
    coverage = np.zeros((120, 160), bool)
    coverage[30:90, 70:80] = True
    objects = np.zeros_like(backdrop)
    objects[coverage] = (0.9, 0.2, 0.6)
    look = sample_look(rng, backdrop, frame_cast(backdrop))
    result = composite(backdrop, objects, coverage, look)
    far = _far_from(coverage, FEATHER_REACH_PX)
    assert np.array_equal(result[far], backdrop[far])
    inside = coverage & _far_from(~coverage, FEATHER_REACH_PX)
    assert np.abs(result[inside] - backdrop[inside]).mean() > 0.05
    assert np.array_equal(backdrop, backdrop.copy())  # the input is not modified


def _carpet_with_lines(line_rgb: tuple[float, float, float]) -> np.ndarray:
    """A green carpet (with pile noise) crossed by field lines of ``line_rgb``: an SPL frame in miniature."""
    rng = np.random.default_rng(4)
    frame = np.clip(np.array([0.18, 0.45, 0.2]) + rng.normal(0, 0.03, (120, 160, 3)), 0, 1)
    frame[50:53, :] = line_rgb
    frame[:, 100:103] = line_rgb
    return frame.astype(np.float32)


def test_the_cast_is_read_from_the_white_lines_not_from_the_green_carpet():
    assert np.allclose(frame_cast(_carpet_with_lines((0.8, 0.8, 0.8))), 1.0, atol=0.01)
    warm = frame_cast(_carpet_with_lines((0.9, 0.8, 0.6)))
    assert np.allclose(warm, np.array([0.9, 0.8, 0.6]) / 0.7667, atol=0.01)
    grey_world = _carpet_with_lines((0.8, 0.8, 0.8)).reshape(-1, 3).mean(axis=0)
    assert grey_world[1] / grey_world.mean() > 1.3  # what the frame's mean colour would have claimed


def test_clipped_pixels_do_not_set_the_cast():
    frame = _carpet_with_lines((0.7, 0.7, 0.8))
    frame[:10, :10] = (1.0, 1.0, 0.5)  # a blown-out yellow lamp
    assert frame_cast(frame)[2] > 1.0 and np.allclose(frame_cast(np.ones((8, 8, 3), np.float32)), 1.0)


def test_labels_over_a_backdrop_do_not_depend_on_the_frame(backdrop_folder):
    """Masks come from the ray-caster alone: the same over any frame; the modelled room can only hide more of a pole
    (its walls occlude what lies behind them, a photo has no depth)."""
    backdrop = load_backdrop(backdrop_folder / "field.jpg")
    other = np.ascontiguousarray(backdrop[::-1])
    camera = PinholeCamera(backdrop.shape[1], backdrop.shape[0])
    checked = 0
    for index in range(8):
        scene = sample_scene(np.random.default_rng([5, index]), camera, goal_posts_in_view=False)
        look = sample_look(np.random.default_rng(index), backdrop, frame_cast(backdrop))
        over, over_other = render_scene(scene, backdrop=backdrop, look=look), render_scene(scene, backdrop=other, look=look)
        assert [(p.cls, p.range_m) for p in over.poles] == [(p.cls, p.range_m) for p in over_other.poles]
        assert all(np.array_equal(a.mask, b.mask) for a, b in zip(over.poles, over_other.poles))
        in_room = {(p.cls, p.position_m): p.mask for p in render_scene(scene).poles}
        for pole in over.poles:
            room_mask = in_room.get((pole.cls, pole.position_m))
            assert room_mask is None or not (room_mask & ~pole.mask).any()
        objects = render_scene(scene, backdrop=np.zeros_like(backdrop), look=look).image.any(axis=2)
        far = _far_from(objects, FEATHER_REACH_PX)
        assert np.array_equal(over.image[far], backdrop[far])
        checked += len(over.poles)
    assert checked > 0


def test_backdrop_dataset_is_reproducible_and_records_its_frames(backdrop_folder, tmp_path):
    job = SynthJob(8, seed=3, backgrounds=scan_backdrops(backdrop_folder), backdrop_share=0.75)
    one = generate_dataset(tmp_path / "a", job, workers=1, progress=False)
    two = generate_dataset(tmp_path / "b", job, workers=2, progress=False)
    files = sorted(p.relative_to(one) for p in one.rglob("*") if p.is_file())
    assert files == sorted(p.relative_to(two) for p in two.rglob("*") if p.is_file())
    assert all((one / f).read_bytes() == (two / f).read_bytes() for f in files)
    images = json.loads((one / "annotations.json").read_text())["images"]
    used = {entry["backdrop"] for entry in images.values()}
    assert used & {"field.jpg", "small.png"} and all(entry["width"] == 640 for entry in images.values())


def test_backlight_share_sets_how_many_backdrop_frames_are_back_lit(backdrop_folder):
    backdrop = load_backdrop(backdrop_folder / "field.jpg")
    cast = frame_cast(backdrop)

    def looks(share):
        return [sample_look(np.random.default_rng(index), backdrop, cast, share) for index in range(200)]
    assert all(look.backlight_gain < 1.0 and look.haze > 0.0 for look in looks(1.0))
    assert all(look.backlight_gain == 1.0 and look.haze == 0.0 for look in looks(0.0))
    default = [look.backlight_gain < 1.0 for look in looks(BACKLIGHT_SHARE)]
    assert 0.1 < np.mean(default) < 0.3
    defaults = [sample_look(np.random.default_rng(index), backdrop, cast) for index in range(20)]
    assert defaults == looks(BACKLIGHT_SHARE)[:20]


def test_synth_backlight_share_darkens_the_poles_and_is_recorded(backdrop_folder, tmp_path):
    """Every frame back-lit draws the same scenes with their poles darker; the set records the share."""
    backgrounds = scan_backdrops(backdrop_folder)

    def pole_brightness(share):
        job = SynthJob(6, seed=4, backgrounds=backgrounds, config=SceneConfig(backlight_share=share))
        out = generate_dataset(tmp_path / f"s{share}", job, workers=1, progress=False)
        values = []
        for sample in load_dataset(out).samples:
            image = cv2.imread(str(sample.image))
            height, width = image.shape[:2]
            values += [image[polygon_to_mask(instance.pixels(width, height), width, height)].mean()
                       for instance in sample.instances]
        return json.loads((out / "annotations.json").read_text())["generator"]["backlight_share"], values
    never, lit = pole_brightness(0.0)
    always, dark = pole_brightness(1.0)
    assert (never, always) == (0.0, 1.0) and lit and dark
    assert np.mean(dark) < 0.7 * np.mean(lit)


@pytest.mark.parametrize("arguments, message", [
    (["--backlight-share", "0.5"], "--backlight-share lights the poles drawn over real frames: give --backgrounds"),
    (["--backlight-share", "1.5", "--backgrounds", "BG"], "--backlight-share 1.5 must lie between 0 and 1")])
def test_cli_refuses_a_backlight_share_it_cannot_use(arguments, message, backdrop_folder, tmp_path, capsys):
    arguments = [str(backdrop_folder) if argument == "BG" else argument for argument in arguments]
    out = tmp_path / "out"
    assert main(["synth", "--out", str(out), "--images", "2", *arguments]) == 2
    error = capsys.readouterr().err
    assert message in error and "Traceback" not in error
    assert not out.exists()


@pytest.mark.parametrize("case, named", [("empty", "no images"), ("text", "not.jpg"), ("tiny", "tiny.png"),
                                         ("cut", "cut.jpg: cannot be decoded whole (a truncated JPEG")])
def test_bad_background_folders_are_refused_with_the_file_named(case, named, tmp_path, capsys):
    folder = tmp_path / "bg"
    folder.mkdir()
    if case == "text":
        (folder / "not.jpg").write_text("this is not an image")
    elif case == "tiny":
        _write_frame(folder / "tiny.png", 16, 16, 0)
    elif case == "cut":  # OpenCV reads it from its file with a grey bottom, which would be composited into frames
        data = _write_frame(folder / "cut.jpg", 640, 480, 0).read_bytes()
        (folder / "cut.jpg").write_bytes(data[: len(data) * 9 // 10])
    out = tmp_path / "out"
    assert main(["synth", "--out", str(out), "--images", "2", "--backgrounds", str(folder)]) == 2
    error = capsys.readouterr().err
    assert named in error and "Traceback" not in error
    assert not out.exists()
