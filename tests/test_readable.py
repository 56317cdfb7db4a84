"""A rendered band's colour is read from the finished pixels; poles that read as another colour are repainted."""
from __future__ import annotations

import colorsys

import numpy as np
import pytest

from detector.datasets.polygons import mask_to_polygon
from detector.synth.generate import MAX_RENDERS, MIN_LABEL_PIXELS, SynthJob, _draw_scene, _render, draw_frame, render_one
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


def test_written_labels_read_as_their_colours_and_misread_poles_are_repainted():
    """Over varied paint some first renders show a pole in another colour; the frames written never label one."""
    job = SynthJob(60, seed=5, width=320, height=240, config=SceneConfig(nominal_paint_share=0.0))
    repainted, checked = 0, 0
    for index in range(job.images):
        sample = render_one(job, index)
        repainted += sample.repaints > 0
        scene, image, labelled, renders = draw_frame(job, index)
        assert renders == sample.repaints + 1
        nameable = [p for p in _render(job, scene).poles if p.mask.sum() >= MIN_LABEL_PIXELS and p.nameable]
        readable = [p for p in nameable if not misread_bands(image, p.cls, p.band_masks)]
        assert [p.cylinder for p in labelled] == [p.cylinder for p in readable], index
        assert [i.cls for i in sample.instances] == [p.cls for p in readable if mask_to_polygon(p.mask) is not None]
        if renders < MAX_RENDERS:  # only the last render may keep a misread pole (unlabelled)
            assert len(readable) == len(nameable), index
        checked += len(readable)
    assert repainted >= 1 and checked >= 60


def test_a_repaint_changes_only_the_misread_poles_paint():
    """The scene rendered again keeps its camera, backdrop, look, distractors and every pole's code and place."""
    job = SynthJob(40, seed=5, width=320, height=240, config=SceneConfig(nominal_paint_share=0.0))
    seen = 0
    for index in range(job.images):
        scene, _, _, renders = draw_frame(job, index)
        if renders == 1:
            continue
        first = _draw_scene(job, index, np.random.default_rng([job.seed, index]), None)
        assert (scene.pose, scene.effects_seed, scene.jpeg_quality, scene.backdrop) == \
            (first.pose, first.effects_seed, first.jpeg_quality, first.backdrop)
        assert np.array_equal(scene.lighting.direction, first.lighting.direction)
        assert len(scene.quads) == len(first.quads) and len(scene.cylinders) == len(first.cylinders)
        changed = 0
        for now, before in zip(scene.cylinders, first.cylinders):
            assert now.label == before.label and np.array_equal(now.base, before.base)
            assert [band[:2] for band in now.bands] == [band[:2] for band in before.bands]
            assert now.bands[0] == before.bands[0]  # the white base
            assert now.label is not None or now.bands == before.bands  # distractors keep their colours
            changed += now.bands != before.bands
        assert 1 <= changed <= sum(c.label is not None for c in scene.cylinders)
        seen += 1
    assert seen >= 1
