"""``poles soup``: two checkpoints of one network blended weight by weight, everything else refused in one line."""
from __future__ import annotations

import hashlib
from pathlib import Path

import pytest
import torch

from detector.cli import main
from detector.model_files import SHIPPED_WEIGHTS
from detector.model_files import read_checkpoint
from naoslam.landmarks import CLASSES


def _tensors(path: Path) -> dict[str, torch.Tensor]:
    checkpoint = read_checkpoint(path)
    return {k: v.float() for k, v in (checkpoint.get("ema") or checkpoint["model"]).state_dict().items()}


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.mark.parametrize("alpha", [0.0, 0.3, 1.0])
def test_soup_interpolates_every_weight_between_the_two_checkpoints(alpha, tiny_run, tmp_path):
    """tiny_run is one epoch fine-tuned from the shipped checkpoint: the same network, other weights."""
    first, second = SHIPPED_WEIGHTS, tiny_run / "weights" / "last.pt"
    out = tmp_path / "soup.pt"
    assert main(["soup", "--weights", str(first), str(second), "--alpha", str(alpha), "--out", str(out)]) == 0
    a, b, blended = _tensors(first), _tensors(second), _tensors(out)
    moved = [name for name in a if a[name].is_floating_point() and not torch.equal(a[name], b[name])]
    assert len(moved) > 100  # the fine-tune changed most tensors, so the blend has something to show
    for name in moved:
        expected = ((1 - alpha) * a[name] + alpha * b[name]).half().float()
        torch.testing.assert_close(blended[name], expected, rtol=0, atol=0)
    checkpoint = read_checkpoint(out)
    assert list(checkpoint["model"].names.values()) == list(CLASSES)
    assert f"{alpha:g} * last.pt" in checkpoint["train_args"]["blend"]


def test_soup_refuses_different_networks_a_bad_alpha_and_its_own_inputs(tiny_run, tmp_path, capsys):
    from ultralytics.nn.tasks import SegmentationModel

    other = tmp_path / "yolov8s.pt"
    network = SegmentationModel("yolov8s-seg.yaml", nc=len(CLASSES), verbose=False)
    torch.save({"model": network.half(), "train_args": {"task": "segment"}, "epoch": -1}, other)
    second = tiny_run / "weights" / "last.pt"
    before = _digest(second)
    cases = [([str(SHIPPED_WEIGHTS), str(other)], "0.5", tmp_path / "a.pt", "different networks"),
             ([str(SHIPPED_WEIGHTS), str(second)], "1.5", tmp_path / "b.pt", "--alpha 1.5 must lie in 0..1"),
             ([str(SHIPPED_WEIGHTS), str(second)], "0.5", second, "last.pt")]
    for weights, alpha, out, message in cases:
        assert main(["soup", "--weights", *weights, "--alpha", alpha, "--out", str(out), "--force"]) == 2
        error = capsys.readouterr().err
        assert message in error and "Traceback" not in error
    assert _digest(second) == before
    assert not (tmp_path / "a.pt").exists() and not (tmp_path / "b.pt").exists()


def test_soup_takes_a_train_run_folder_for_its_best_checkpoint(tiny_run, tmp_path):
    """`poles train` prints its run folder; every command that reads a checkpoint takes that folder too."""
    out = tmp_path / "soup.pt"
    assert main(["soup", "--weights", str(SHIPPED_WEIGHTS), str(tiny_run), "--alpha", "1", "--out", str(out)]) == 0
    best = _tensors(tiny_run / "weights" / "best.pt")
    assert all(torch.equal(tensor, best[name]) for name, tensor in _tensors(out).items())
    assert "1 * best.pt" in read_checkpoint(out)["train_args"]["blend"]
