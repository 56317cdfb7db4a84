"""How far one model's F1 lies from another's on the same frames, with the spread that the choice of frames gives.

Two models counted on the same held-out frames differ by a few detections; whether that is a better model or a
lucky set of frames is what a paired bootstrap over frames answers (``scipy.stats.bootstrap``): draw the frames
again with replacement, count both models on the same draw, and take the spread of the F1 difference (Efron and
Tibshirani, "An Introduction to the Bootstrap", 1993). Frames, not poles, are drawn, because a frame's poles share
its light, backdrop and camera and are not independent.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats

from detector.evaluation.results import FrameCounts
from detector.records import JsonRecord

#: The name of the shipped model, as installed, wherever another model is compared with it (a row, a folder).
REFERENCE = "shipped"
#: Resamples of the frames: between seeds the interval's ends move by about 0.0003 of F1 (s.d.) on 400 frames, 0.002
#: on 40.
BOOTSTRAP_DRAWS = 2000
BOOTSTRAP_SEED = 0
#: Resamples drawn together: 10,000 frames peak near 60 MB.
DRAWS_AT_ONCE = 100


@dataclass(frozen=True)
class F1Difference(JsonRecord):
    """``second``'s F1 minus ``first``'s on the same frames, and its 95 % interval over frames."""

    difference: float
    low: float
    high: float


def f1_difference(first: Sequence[FrameCounts], second: Sequence[FrameCounts], draws: int = BOOTSTRAP_DRAWS,
                  seed: int = BOOTSTRAP_SEED) -> F1Difference:
    """Paired bootstrap of the F1 difference between two evaluations' counts per frame (``Evaluation.per_image``).
    Both must list the same frames in the same order."""
    if [row.image for row in first] != [row.image for row in second]:
        raise ValueError("the two evaluations were not made on the same frames: compare models on one split")
    columns = (*_counts(first).T, *_counts(second).T)  # tp, fp, fn of the first, then of the second, per frame
    if len(columns[0]) < 2:  # one frame cannot be resampled: its difference is all there is
        difference = float(_difference(*columns, axis=-1))
        return F1Difference(difference, difference, difference)
    result = stats.bootstrap(columns, _difference, n_resamples=draws, batch=DRAWS_AT_ONCE, vectorized=True,
                             paired=True, method="percentile", random_state=np.random.default_rng(seed))
    interval = result.confidence_interval
    return F1Difference(float(_difference(*columns, axis=-1)), float(interval.low), float(interval.high))


def _difference(tp_a, fp_a, fn_a, tp_b, fp_b, fn_b, axis: int = -1) -> np.ndarray:
    """The second model's pooled F1 less the first's, over the frames along ``axis``."""
    return _f1(tp_b.sum(axis), fp_b.sum(axis), fn_b.sum(axis)) - _f1(tp_a.sum(axis), fp_a.sum(axis), fn_a.sum(axis))


def _counts(per_image: Sequence[FrameCounts]) -> np.ndarray:
    return np.array([[row.counts.tp, row.counts.fp, row.counts.fn] for row in per_image],
                    dtype=np.int64).reshape(-1, 3)


def _f1(tp: np.ndarray, fp: np.ndarray, fn: np.ndarray) -> np.ndarray:
    """F1 = 2 TP / (2 TP + FP + FN), as ``Counts.precision_recall`` gives it, for many resamples at once; 1 where
    nothing was there and nothing was found."""
    denominator = 2 * tp + fp + fn
    return np.where(denominator > 0, 2 * tp / np.maximum(denominator, 1), 1.0)
