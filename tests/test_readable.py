"""A rendered band's colour is read from the finished pixels; frames whose poles read as another colour are redrawn."""
from __future__ import annotations

import colorsys

import numpy as np
import pytest

from detector.datasets.polygons import mask_to_polygon
from detector.synth.effects import apply_camera_effects, camera_effects
from detector.synth.generate import MAX_DRAWS, MIN_LABEL_PIXELS, SynthJob, _draw_scene, render_one
from detector.synth.objects import BAND_RGB
from detector.synth.readable import band_colour, misread_bands
from detector.synth.scene import SceneConfig


def _patch(hsv_opencv: tuple[int, int, int], noise: float = 0.0, size: int = 20) -> tuple[np.ndarray, np.ndarray]:
    """A uint8 RGB patch of one OpenCV HSV colour (hue 0..179), with optional Gaussian noise, and its full mask."""
    h, s, v = hsv_opencv
    rgb = np.array(colorsys.hsv_to_rgb(h / 180, s / 255, v / 255)) * 255
    image = np.tile(rgb, (size, size, 1)) + np.random.default_rng(0).normal(0.0, noise, (size, size, 3))
    return np.clip(image + 0.5, 0, 255).astype(np.uint8), np.ones((size, size), bool)


@pytest.mark.parametrize("letter", sorted(BAND_RGB))
def test_the_nominal_paints_read_as_themselves(letter):
    image = np.tile((np.array(BAND_RGB[letter]) * 255).astype(np.uint8), (10, 10, 1))
    assert band_colour(image, np.ones((10, 10), bool)) == letter


@pytest.mark.parametrize("hue, expected", [(100, "b"), (60, "g"), (27, "y"), (165, "p"), (178, "p"), (2, "p"),
                                           (40, "y"), (43, "g"), (130, "b"), (138, "p")])
def test_a_hue_is_named_by_the_nearest_colour_filter_range_round_the_circle(hue, expected):
    assert band_colour(*_patch((hue, 200, 180), noise=3.0)) == expected


@pytest.mark.parametrize("hsv", [(100, 200, 20), (60, 30, 200), (100, 255, 0)])
def test_a_band_too_dark_or_too_grey_to_carry_a_hue_gives_no_verdict(hsv):
    assert band_colour(*_patch(hsv)) is None


def test_a_blue_band_that_looks_green_is_misread_and_only_that_band():
    blue_as_green, mask = _patch((60, 200, 180))
    pink, _ = _patch((165, 200, 180))
    image = np.concatenate([pink, blue_as_green])
    top, bottom = np.zeros((40, 20), bool), np.zeros((40, 20), bool)
    top[:20], bottom[20:] = True, True
    assert misread_bands(image, "pb", (top, bottom)) == ["b"]
    assert misread_bands(image, "pg", (top, bottom)) == []
    assert misread_bands(image, "pb", (top, np.zeros_like(bottom))) == []  # an empty band contradicts nothing


def test_written_labels_read_as_their_colours_and_misread_frames_are_drawn_again():
    """Over varied paint some first draws show a pole in another colour; the frames written never label one."""
    job = SynthJob(60, seed=5, width=320, height=240, config=SceneConfig(nominal_paint_share=0.0))
    effects, redrawn, checked = camera_effects(), 0, 0
    for index in range(job.images):
        sample = render_one(job, index)
        redrawn += sample.redraws > 0
        rng = np.random.default_rng([job.seed, index] if sample.redraws == 0 else [job.seed, index, sample.redraws])
        scene, frame, _ = _draw_scene(job, index, rng, None)
        image = apply_camera_effects(effects, (frame.image * 255.0 + 0.5).astype(np.uint8), scene.effects_seed)
        labelled = [p for p in frame.poles if p.mask.sum() >= MIN_LABEL_PIXELS and p.nameable
                    and mask_to_polygon(p.mask) is not None]
        readable = [p.cls for p in labelled if not misread_bands(image, p.cls, p.band_masks)]
        assert [instance.cls for instance in sample.instances] == readable, index
        if sample.redraws < MAX_DRAWS - 1:  # only the last draw may keep a misread pole (unlabelled)
            assert len(readable) == len(labelled), index
        checked += len(readable)
    assert redrawn >= 1 and checked >= 60
