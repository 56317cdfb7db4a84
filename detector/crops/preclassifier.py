"""The preclassifier: a network of a few thousand parameters that looks at every candidate's crop before the crop
network does and rejects the windows that hold no pole, chosen for recall (HULKs' cascade on the Nao runs one so).

It sees each window as a 12x24 crop (a quarter of the crop network's pixels, cut by the same function), normalised
inside the graph as the crop network's is, through two 3x3 convolutions of stride 2 and two small dense layers: about
41 thousand multiply-adds a crop, a thirtieth of the crop network's. Only the windows it passes are cut at the crop
network's size. Trained on the crop network's own training windows (pole or no pole, the same augmentation), its threshold is the
highest that keeps ``KEPT_POLES`` of the valid pole windows the crop network itself names right. The exported
graph (ONNX, sigmoid inside) travels inside the crop network's file (:mod:`naoslam.perception.preclassifier`).
"""
from __future__ import annotations

import io
import math
import time
import warnings
from dataclasses import dataclass

import numpy as np
import onnxruntime as ort
import torch
from torch import nn

from detector.crops.network import Normalise, PoleCropNet
from detector.crops.samples import NO_POLE, CropSet
from detector.crops.settings import CropTrainSettings
from detector.crops.train import augment, one_cycle, tensors
from naoslam.perception.preclassifier import PRECLASSIFIER_INPUT

#: Share of the valid pole crops the crop network names right that the preclassifier's threshold keeps.
KEPT_POLES = 0.99
#: The preclassifier's crop (width, height), channels of its two convolutions and width of its hidden dense layer.
PRECLASSIFIER_SIZE_WH = (12, 24)
CHANNELS, HIDDEN = (8, 16), 16
#: Largest difference allowed between the exported graph's and PyTorch's probabilities.
AGREEMENT = 1e-4


class Preclassifier(nn.Module):
    """(N, 3, 24, 12) BGR crops in 0..1 -> (N, 1) logit that the crop holds a pole."""

    def __init__(self, size_wh: tuple[int, int] = PRECLASSIFIER_SIZE_WH):
        super().__init__()
        self.size_wh = size_wh
        first, second = CHANNELS
        cells = (size_wh[0] // 4) * (size_wh[1] // 4)
        self.body = nn.Sequential(
            Normalise(),
            nn.Conv2d(3, first, 3, stride=2, padding=1, bias=False), nn.BatchNorm2d(first), nn.ReLU(inplace=True),
            nn.Conv2d(first, second, 3, stride=2, padding=1, bias=False), nn.BatchNorm2d(second),
            nn.ReLU(inplace=True), nn.Flatten(), nn.Linear(second * cells, HIDDEN), nn.ReLU(inplace=True),
            nn.Linear(HIDDEN, 1))

    def forward(self, crops: torch.Tensor) -> torch.Tensor:
        return self.body(crops)


class _Deployed(nn.Module):
    """What the robot runs: the probability that each crop holds a pole, (N, 1)."""

    def __init__(self, network: Preclassifier):
        super().__init__()
        self.network = network

    def forward(self, crops: torch.Tensor) -> torch.Tensor:
        return torch.sigmoid(self.network(crops))


@dataclass(frozen=True)
class PreclassifierResult:
    """A trained preclassifier's threshold and what it keeps and rejects of the valid crops at it."""

    threshold: float
    #: Share of the valid pole crops the crop network names right that pass.
    kept_poles: float
    #: Share of the valid no-pole crops rejected.
    rejected_clutter: float
    parameters: int
    minutes: float


def train_preclassifier(train: CropSet, valid: CropSet, valid_full: CropSet, crop_network: PoleCropNet,
                        settings: CropTrainSettings = CropTrainSettings(epochs=10),
                        log=print) -> tuple[Preclassifier, PreclassifierResult]:
    """Train a preclassifier on ``train`` (crops of the crop network's training windows at the preclassifier's
    size; pole against no pole) and choose its threshold on ``valid``, the valid windows at its size, against
    ``valid_full``, the same windows at the crop network's size, where ``crop_network`` names the poles it finds."""
    torch.manual_seed(settings.seed)
    torch.set_num_threads(settings.threads)
    network = Preclassifier((train.crops.shape[2], train.crops.shape[1]))
    images, classes, boxes = tensors(train)
    targets = (classes != NO_POLE).float()
    optimiser = torch.optim.AdamW(network.parameters(), lr=settings.learning_rate, weight_decay=settings.weight_decay)
    schedule = one_cycle(optimiser, settings.learning_rate, settings.epochs * math.ceil(len(images) / settings.batch))
    generator = torch.Generator().manual_seed(settings.seed)
    began = time.perf_counter()
    for epoch in range(1, settings.epochs + 1):
        network.train()
        order, total = torch.randperm(len(images), generator=generator), 0.0
        for i in range(0, len(order), settings.batch):
            batch = order[i:i + settings.batch]
            batch_images, _ = augment(images[batch], boxes[batch], generator, settings.colour_jitter)
            loss = nn.functional.binary_cross_entropy_with_logits(network(batch_images)[:, 0], targets[batch])
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
            schedule.step()
            total += loss.item() * len(batch)
        log(f"preclassifier epoch {epoch}/{settings.epochs}: loss {total / len(images):.4f}")
    network.eval()
    threshold, kept, rejected = choose_threshold(network, valid, valid_full, crop_network)
    log(f"preclassifier threshold {threshold:.3f}: keeps {100 * kept:.1f} % of the valid poles the crop network "
        f"names, rejects {100 * rejected:.1f} % of the valid windows without a pole")
    return network, PreclassifierResult(threshold, kept, rejected, sum(p.numel() for p in network.parameters()),
                                        round((time.perf_counter() - began) / 60, 2))


@torch.no_grad()
def probabilities(network: nn.Module, crops: CropSet) -> np.ndarray:
    """(N, outputs) of a network's logits on a crop set, in batches."""
    images, _, _ = tensors(crops)
    return torch.cat([network(images[i:i + 2048]) for i in range(0, len(images), 2048)]).numpy()


def choose_threshold(network: Preclassifier, valid: CropSet, valid_full: CropSet, crop_network: PoleCropNet,
                     kept_poles: float = KEPT_POLES) -> tuple[float, float, float]:
    """The highest probability threshold that keeps ``kept_poles`` of the valid pole windows the crop network names
    right (the class, probability 0.5 or more; every pole window where it names none yet), with the share kept and
    the share of no-pole windows rejected.
    ``valid`` and ``valid_full`` are the same windows, cut at the preclassifier's and the crop network's size."""
    if len(valid) != len(valid_full) or not np.array_equal(valid.classes, valid_full.classes):
        raise ValueError(f"the preclassifier's {len(valid)} valid crops are not the crop network's {len(valid_full)} "
                         "windows - cut both from the same frames with the same seed")
    scores = 1 / (1 + np.exp(-probabilities(network, valid)[:, 0]))
    outputs = probabilities(crop_network.eval(), valid_full)
    logits = outputs[:, :NO_POLE + 1]
    named = np.exp(logits - logits.max(axis=1, keepdims=True))
    named /= named.sum(axis=1, keepdims=True)
    poles = valid.classes != NO_POLE
    right = poles & (named.argmax(axis=1) == valid.classes) & (named[:, :NO_POLE].max(axis=1) >= 0.5)
    if not right.any():  # a network trained on a few frames names none yet: keep its labelled poles instead
        right = poles
    if not right.any():
        raise ValueError("the valid frames hold no pole: no threshold can be chosen to keep poles - give valid "
                         "frames with poles (`poles split` makes them)")
    threshold = float(np.quantile(scores[right], 1 - kept_poles, method="lower"))
    return threshold, float((scores[right] >= threshold).mean()), float((scores[~poles] < threshold).mean())


def preclassifier_onnx(network: Preclassifier, check_crops: np.ndarray) -> bytes:
    """The preclassifier as ONNX bytes (batch of any size, sigmoid inside), checked against PyTorch on
    ``check_crops`` (N, H, W, 3 BGR uint8); ValueError when they disagree."""
    deployed = _Deployed(network.eval()).eval()
    width, height = network.size_wh
    buffer = io.BytesIO()
    with warnings.catch_warnings():  # the TorchScript exporter: all a graph of plain layers needs
        warnings.simplefilter("ignore", DeprecationWarning)
        torch.onnx.export(deployed, torch.zeros(1, 3, height, width), buffer, input_names=[PRECLASSIFIER_INPUT],
                          output_names=["pole"], dynamic_axes={PRECLASSIFIER_INPUT: {0: "n"}, "pole": {0: "n"}},
                          opset_version=17, dynamo=False)
    model = buffer.getvalue()
    blob = check_crops.transpose(0, 3, 1, 2).astype(np.float32) / 255.0
    session = ort.InferenceSession(model, providers=["CPUExecutionProvider"])
    with torch.no_grad():
        difference = float(np.abs(session.run(None, {PRECLASSIFIER_INPUT: blob})[0]
                                  - deployed(torch.from_numpy(blob)).numpy()).max()) if len(blob) else 0.0
    if difference > AGREEMENT:
        raise ValueError(f"the exported preclassifier differs from PyTorch by {difference:.2g} (at most "
                         f"{AGREEMENT:g})")
    return model
