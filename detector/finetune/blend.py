"""The blend of the shipped model and a team's fine-tune that ``poles finetune`` ships: every share in
``BLEND_SHARES`` is written (``poles soup``'s blend) and scored on the export's valid split. Half and half (WiSE-FT's
middle, which keeps most of what the shipped model knew) ships unless the valid split shows another share to be
better frame by frame: a one-sided sign test over the frames where the two differ (docs/finetune.md)."""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

from scipy.stats import binomtest

from detector.evaluation.predictors import Predictor
from detector.evaluation.results import Counts, FrameCounts
from detector.evaluation.run import evaluate
from detector.finetune.recipe import BLEND_SHARES, DEFAULT_BLEND_SHARE, SIGN_TEST_LEVEL
from detector.records import JsonRecord


@dataclass(frozen=True)
class BlendScore(JsonRecord):
    """One share of the fine-tune on the valid split, counted as ``poles evaluate`` counts, and how it fares frame by
    frame against the default share."""

    share: float
    counts: Counts
    precision: float
    recall: float
    f1: float
    #: False positives plus missed poles, by image name.
    frame_errors: dict[str, int]
    frames_better: int = 0
    frames_worse: int = 0


@dataclass(frozen=True)
class BlendChoice(JsonRecord):
    """Every share's score, the share chosen and its checkpoint."""

    shares: tuple[BlendScore, ...]
    chosen: float
    weights: Path


def blend_path(folder: Path, share: float) -> Path:
    """Where the blend with the fine-tune's ``share`` is written."""
    return Path(folder) / f"blend-{round(100 * share):03d}.pt"


def frame_errors(per_image: tuple[FrameCounts, ...]) -> dict[str, int]:
    """Each frame's errors, false positives plus missed poles, by image name."""
    return {row.image: row.counts.fp + row.counts.fn for row in per_image}


def frames_against(errors: dict[str, int], default_errors: dict[str, int]) -> tuple[int, int]:
    """On how many frames a share with per-frame ``errors`` makes fewer errors than the default share, and on how
    many more."""
    better = sum(errors[image] < default_errors[image] for image in default_errors)
    worse = sum(errors[image] > default_errors[image] for image in default_errors)
    return better, worse


def beats_default(better: int, worse: int) -> bool:
    """Whether ``better`` frames against ``worse`` show a share to beat the default: a one-sided sign test at
    ``SIGN_TEST_LEVEL``."""
    return better > worse and binomtest(better, better + worse, 0.5, alternative="greater").pvalue <= SIGN_TEST_LEVEL


def pick_share(scores: list[BlendScore]) -> float:
    """The share to ship from each share's valid figures: among the shares that beat ``DEFAULT_BLEND_SHARE`` frame by
    frame, the best F1 (a tie to the share nearest it); else the default."""
    winners = [score for score in scores if beats_default(score.frames_better, score.frames_worse)]
    if not winners:
        return DEFAULT_BLEND_SHARE
    best = max(winners, key=lambda score: (round(score.f1, 9), -abs(score.share - DEFAULT_BLEND_SHARE)))
    return best.share


def choose_blend(shipped: Path, finetuned: Path, data: Path, folder: Path, conf: float,
                 predictor_of: Callable[[Path], Predictor],
                 blend: Callable[[Path, Path, float, Path], Path], frames: int | None = None) -> BlendChoice:
    """Write (``blend(shipped, finetuned, share, out)``) and score (``predictor_of(checkpoint)``) every blend on
    ``data``'s valid split (its first ``frames``, or all) at ``conf``; returns each share's figures and the chosen
    share (its checkpoint at ``blend_path(folder, share)``)."""
    scores = []
    for share in BLEND_SHARES:
        weights = blend(shipped, finetuned, share, blend_path(folder, share))
        metrics = evaluate(predictor_of(weights), data, folder / f"valid-{round(100 * share):03d}", "valid",
                           conf, progress=False, frames=frames, check=False)
        scores.append(BlendScore(share, metrics.counts, metrics.precision, metrics.recall, metrics.f1,
                                 frame_errors(metrics.per_image)))
    default = next(score for score in scores if score.share == DEFAULT_BLEND_SHARE)
    against = [frames_against(score.frame_errors, default.frame_errors) for score in scores]
    scores = [replace(score, frames_better=better, frames_worse=worse)
              for score, (better, worse) in zip(scores, against)]
    chosen = pick_share(scores)
    return BlendChoice(tuple(scores), chosen, blend_path(folder, chosen))
