"""``poles finetune --model robot``: the robot's crop network fine-tuned on a team's frames and the rehearsal,
blended with the shipped one and exported, with the same stages as the accurate model's YOLOv8 (``pipeline``).

Training crops come from the mixed set's train frames (the team's augmented frames and the rendered rehearsal), the
best epoch is picked on the crops of the team's valid frames; a blend is the shipped and the fine-tuned network
weight by weight; each checkpoint is judged through its ONNX export, as the robot runs it (boxes matched by IoU).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from detector.crops.curves import plot_crop_history
from detector.crops.export import export_crop_network
from detector.crops.samples import NO_POLE, crops_of_dataset
from detector.crops.settings import CropTrainSettings
from detector.crops.train import load_checkpoint, save_checkpoint, train_crop_network
from detector.datasets.io import load_dataset
from detector.evaluation.predictors import RuntimePredictor, Predictor
from detector.finetune.results import ExportedModel
from detector.model_files import ROBOT_WEIGHTS, add_metadata, read_info
from detector.training.summary import TrainingSummary
from naoslam.shipped import OPERATING_CONF_KEY, resolve_model, robot_path

#: Crops that check an export against PyTorch when none of the team's are at hand.
CHECK_CROPS = 16


def train(data: Path, run: Path, weights: Path, epochs: int, minutes: float, learning_rate: float,
          seed: int) -> TrainingSummary:
    """Fine-tune the crop network at ``weights`` on ``data``'s train frames into ``run``/poles-robot.pt: the last
    epoch's weights, as for the accurate model (a team's valid split is too small to pick an epoch on)."""
    start = load_checkpoint(weights)
    dataset = load_dataset(data)
    train_crops = crops_of_dataset(dataset, ("train",), start.size_wh, seed=seed)
    valid_crops = crops_of_dataset(dataset, ("valid",), start.size_wh, seed=seed + 1)
    if not (valid_crops.classes != NO_POLE).any():
        valid_crops = train_crops  # a valid split without a pole: each epoch reports on the train crops
    settings = CropTrainSettings(epochs=epochs, learning_rate=learning_rate, seed=seed, minutes=minutes,
                                 keep="last")
    network, history = train_crop_network(train_crops, valid_crops, settings, start)
    run.mkdir(parents=True, exist_ok=True)
    checkpoint = save_checkpoint(network, run / "poles-robot.pt", history, settings)
    curves = plot_crop_history(history, run / "training_curves.png")
    return TrainingSummary("crop network", weights, checkpoint, curves, len(history),
                           round(sum(h.seconds for h in history) / 60, 2))


def blend(shipped: Path, finetuned: Path, share: float, out: Path) -> Path:
    """``(1 - share) * shipped + share * finetuned``, every tensor (batch-norm statistics too), saved at ``out``."""
    first, second = load_checkpoint(shipped), load_checkpoint(finetuned)
    a, b = first.state_dict(), second.state_dict()
    second.load_state_dict({name: (1 - share) * a[name] + share * b[name] if b[name].is_floating_point() else b[name]
                            for name in b})
    settings = CropTrainSettings(**torch.load(str(finetuned), weights_only=False)["settings"])
    return save_checkpoint(second, out, [], settings)


def onnx_of(weights: Path) -> Path:
    """The checkpoint's ONNX beside it (written once), with the shipped model's metadata (threshold, calibration)."""
    model = Path(weights).with_suffix(".onnx")
    if not model.is_file() or model.stat().st_mtime < Path(weights).stat().st_mtime:
        export(weights, model)
    return model


def export(weights: Path, model: Path) -> ExportedModel:
    """The crop network at ``weights`` as the robot's ONNX file, checked against PyTorch, carrying the shipped robot
    model's threshold and range calibration (its boxes are measured in frame pixels, so the laws hold)."""
    network = load_checkpoint(weights)
    width, height = network.size_wh
    check = np.random.default_rng(0).integers(0, 256, (CHECK_CROPS, height, width, 3), dtype=np.uint8)
    stamp = shipped_metadata()
    difference = export_crop_network(network, model, check, stamp[OPERATING_CONF_KEY])
    add_metadata(model, **{key: value for key, value in stamp.items() if key != "training"})
    return ExportedModel(model, None, "calibration" in stamp, onnx_difference=difference)


def shipped_metadata() -> dict:
    """The shipped robot model's metadata: its operating threshold and range calibration."""
    return read_info(resolve_model("shipped-robot")).extra


def predictor(weights: Path) -> Predictor:
    """How a checkpoint is judged: its ONNX export through the runtime's two-stage front end (the shipped checkpoint
    by the shipped ONNX, so nothing is ever written into the installation)."""
    if Path(weights).resolve() == ROBOT_WEIGHTS.resolve():
        return RuntimePredictor(robot_path())
    return RuntimePredictor(onnx_of(weights))
