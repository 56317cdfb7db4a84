"""``poles soup``: blend two checkpoints of one network weight by weight, (1 - alpha) * first + alpha * second.

A model fine-tuned from another shares its basin, and the straight line between the two often beats both: a "model
soup" (Wortsman et al. 2022), which WiSE-FT found also keeps more of the first model's robustness to frames unlike the
fine-tuning data. The shipped pole model is such a blend (docs/model-card.md); a team can blend the
shipped checkpoint with its own fine-tune the same way. No training, no data: every floating-point tensor of the two
models (batch-norm running statistics included) is interpolated; the result carries the second checkpoint's
metadata, with the blend recorded in its training arguments.
"""
from __future__ import annotations

import copy
from pathlib import Path

import torch

from detector.outputs import check_output_file
from detector.model_files import read_checkpoint
from detector.atomic import atomic_path


def _network(checkpoint: dict) -> torch.nn.Module:
    """The model a checkpoint would be used with: its EMA when it holds one (as Ultralytics saves)."""
    return checkpoint.get("ema") or checkpoint["model"]


def blend_checkpoints(first: Path, second: Path, alpha: float, out: Path, force: bool = False) -> Path:
    """Write ``(1 - alpha) * first + alpha * second`` to ``out`` (atomically) and return it.

    Refuses an ``alpha`` outside 0-1, an ``out`` that is one of the inputs (or exists, without ``force``) and two
    checkpoints whose networks differ in any tensor's name or shape.
    """
    if not 0.0 <= alpha <= 1.0:
        raise ValueError(f"--alpha {alpha} must lie in 0..1 (0: the first checkpoint, 1: the second)")
    out = check_output_file(out, force, (Path(first), Path(second)))
    base, other = read_checkpoint(first), read_checkpoint(second)
    a, b = _network(base).float().state_dict(), _network(other).float().state_dict()
    mismatched = [name for name in a.keys() | b.keys() if name not in a or name not in b or a[name].shape != b[name].shape]
    if mismatched:
        raise ValueError(f"{first} and {second} are different networks ({len(mismatched)} tensors differ, e.g. "
                         f"{sorted(mismatched)[0]!r}): blend two checkpoints of one architecture, e.g. the shipped "
                         "model and a fine-tune of it")
    blended = {name: (1 - alpha) * a[name] + alpha * b[name] if a[name].is_floating_point() else b[name] for name in b}
    network = copy.deepcopy(_network(other)).float()
    network.load_state_dict(blended)
    train_args = {**other.get("train_args", {}), "blend": f"(1 - {alpha:g}) * {Path(first).name} + {alpha:g} * "
                                                          f"{Path(second).name}"}
    soup = {**other, "model": network.half(), "ema": None, "optimizer": None, "train_args": train_args, "epoch": -1}
    with atomic_path(out) as tmp:
        torch.save(soup, str(tmp))
    return out
