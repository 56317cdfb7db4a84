"""The paired bootstrap of two models' F1 on the same frames."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from detector.evaluation.paired import f1_difference
from detector.evaluation.results import Counts, FrameCounts


def _frames(counts: list[tuple[int, int, int]]) -> list[FrameCounts]:
    return [FrameCounts(f"frame_{i:03d}.jpg", Counts(tp, fp, fn)) for i, (tp, fp, fn) in enumerate(counts)]


def _pooled_f1(frames: list[FrameCounts]) -> float:
    return sum((frame.counts for frame in frames), Counts()).precision_recall()[2]


def test_a_model_against_itself_differs_by_nothing_on_every_draw():
    frames = _frames([(2, 1, 0), (0, 0, 1), (3, 0, 0), (1, 2, 1)] * 10)
    same = f1_difference(frames, frames)
    assert (same.difference, same.low, same.high) == (0.0, 0.0, 0.0)


def test_a_model_better_on_every_frame_has_an_interval_above_zero_and_a_worse_one_below():
    rng = np.random.default_rng(3)
    base = [(int(rng.integers(0, 4)), int(rng.integers(0, 2)), int(rng.integers(1, 3))) for _ in range(60)]
    better = [(tp + 1, fp, fn - 1) for tp, fp, fn in base]  # one more pole found in every frame
    first, second = _frames(base), _frames(better)
    up = f1_difference(first, second)
    assert 0 < up.low <= up.difference <= up.high
    assert up.difference == pytest.approx(_pooled_f1(second) - _pooled_f1(first))
    down = f1_difference(second, first)
    assert down.high < 0 and down.difference == pytest.approx(-up.difference)


def test_a_few_frames_that_disagree_give_an_interval_that_spans_zero():
    """Two models that each miss one pole of 80, one with a false positive as well: no basis to prefer either."""
    first, second = [(2, 0, 0)] * 40, [(2, 0, 0)] * 40
    first[5], second[3], second[17] = (1, 0, 1), (1, 0, 1), (2, 1, 0)
    change = f1_difference(_frames(first), _frames(second))
    assert change.difference < 0 and change.low < 0 < change.high


@settings(max_examples=30, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 5), st.integers(0, 3), st.integers(0, 3)), min_size=1, max_size=30),
       st.lists(st.tuples(st.integers(0, 5), st.integers(0, 3), st.integers(0, 3)), min_size=1, max_size=30))
def test_the_difference_is_the_pooled_f1_of_counting_and_the_same_seed_gives_the_same_interval(first, second):
    n = min(len(first), len(second))
    a, b = _frames(first[:n]), _frames(second[:n])
    change = f1_difference(a, b, draws=200)
    assert change.difference == pytest.approx(_pooled_f1(b) - _pooled_f1(a), abs=1e-12)
    assert f1_difference(a, b, draws=200) == change


def test_evaluations_of_different_frames_are_refused():
    with pytest.raises(ValueError, match="not made on the same frames"):
        f1_difference(_frames([(1, 0, 0)] * 3), _frames([(1, 0, 0)] * 4))
