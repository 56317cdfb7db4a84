"""The blend of the shipped model and a team's fine-tune that ``poles finetune`` ships: every share in
``BLEND_SHARES`` is written (``poles soup``'s blend) and scored on the export's valid split. Half and half (WiSE-FT's
middle, which keeps most of what the shipped model knew) ships unless the valid split shows another share to be
better frame by frame: a one-sided sign test over the frames where the two differ (docs/finetune.md)."""
from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from scipy.stats import binomtest

from detector.evaluation.predictors import Predictor
from detector.evaluation.run import evaluate
from detector.finetune.recipe import BLEND_SHARES, DEFAULT_BLEND_SHARE, SIGN_TEST_LEVEL


def blend_path(folder: Path, share: float) -> Path:
    """Where the blend with the fine-tune's ``share`` is written."""
    return Path(folder) / f"blend-{round(100 * share):03d}.pt"


def frame_errors(per_image: list[dict]) -> dict[str, int]:
    """Each frame's errors, false positives plus missed poles, by image name."""
    return {row["image"]: row["fp"] + row["fn"] for row in per_image}


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


def pick_share(scores: list[dict]) -> float:
    """The share to ship from each share's valid figures (``share``, ``f1``, ``frames_better``, ``frames_worse``
    against the default): among the shares that beat ``DEFAULT_BLEND_SHARE``, the best F1 (a tie to the share
    nearest it); else the default."""
    winners = [row for row in scores if beats_default(row["frames_better"], row["frames_worse"])]
    if not winners:
        return DEFAULT_BLEND_SHARE
    best = max(winners, key=lambda row: (round(row["f1"], 9), -abs(row["share"] - DEFAULT_BLEND_SHARE)))
    return best["share"]


def choose_blend(shipped: Path, finetuned: Path, data: Path, folder: Path, conf: float,
                 predictor_of: Callable[[Path], Predictor], blend: Callable[[Path, Path, float, Path], Path]) -> dict:
    """Write (``blend(shipped, finetuned, share, out)``) and score (``predictor_of(checkpoint)``) every blend on
    ``data``'s valid split at ``conf``; returns each share's figures and the chosen share (its checkpoint at
    ``blend_path(folder, share)``)."""
    scores = []
    for share in BLEND_SHARES:
        weights = blend(shipped, finetuned, share, blend_path(folder, share))
        metrics = evaluate(predictor_of(weights), data, folder / f"valid-{round(100 * share):03d}", "valid",
                           conf, progress=False)
        scores.append({"share": share, "f1": metrics["f1"], "precision": metrics["precision"],
                       "recall": metrics["recall"], "tp": metrics["tp"], "fp": metrics["fp"], "fn": metrics["fn"],
                       "frame_errors": frame_errors(metrics["per_image"])})
    default = next(row for row in scores if row["share"] == DEFAULT_BLEND_SHARE)
    for row in scores:
        row["frames_better"], row["frames_worse"] = frames_against(row["frame_errors"], default["frame_errors"])
    chosen = pick_share(scores)
    return {"shares": scores, "chosen": chosen, "weights": str(blend_path(folder, chosen))}
