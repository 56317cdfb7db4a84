"""The blend of the shipped model and a team's fine-tune that ``poles finetune`` ships: every share in
``BLEND_SHARES`` is written (``poles soup``'s blend) and scored on the export's valid split; the best F1 wins, a tie
going to the share nearest one half (WiSE-FT's middle, which keeps most of what the shipped model knew)."""
from __future__ import annotations

from pathlib import Path

from detector.evaluation.predictors import TorchPredictor
from detector.evaluation.run import evaluate
from detector.finetune.recipe import BLEND_SHARES
from detector.training.soup import blend_checkpoints


def blend_path(folder: Path, share: float) -> Path:
    """Where the blend with the fine-tune's ``share`` is written."""
    return Path(folder) / f"blend-{round(100 * share):03d}.pt"


def choose_blend(shipped: Path, finetuned: Path, data: Path, folder: Path, conf: float, imgsz: int) -> dict:
    """Write and score every blend on ``data``'s valid split at ``conf``; returns each share's figures and the
    chosen share (its checkpoint at ``blend_path(folder, share)``)."""
    scores = []
    for share in BLEND_SHARES:
        weights = blend_checkpoints(shipped, finetuned, share, blend_path(folder, share), force=True)
        metrics = evaluate(TorchPredictor(weights, imgsz), data, folder / f"valid-{round(100 * share):03d}", "valid",
                           conf, progress=False)
        scores.append({"share": share, "f1": metrics["f1"], "precision": metrics["precision"],
                       "recall": metrics["recall"], "tp": metrics["tp"], "fp": metrics["fp"], "fn": metrics["fn"]})
    best = max(scores, key=lambda row: (round(row["f1"], 9), -abs(row["share"] - 0.5)))
    return {"shares": scores, "chosen": best["share"], "weights": str(blend_path(folder, best["share"]))}
