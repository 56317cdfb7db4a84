"""Training the crop network on a two-core CPU: class cross-entropy on every crop, an L1 loss on the box of every
pole crop, AdamW with a cosine schedule, horizontal flips and brightness changes; the epoch with the best validation
score (pole crops named right with box IoU >= 0.5, minus no-pole crops taken for poles) is kept.

With a teacher (a trained crop network, larger as a rule), every crop's class scores also learn the teacher's: its
softened probabilities on the un-augmented crop, run once before the first epoch, against the student's (Hinton's
distillation: how much a window looks like each pole and like clutter, which a hard label does not say). The boxes
learn from the labels alone."""
from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch
from torch import nn

from detector.atomic import atomic_path
from detector.crops.network import CropArchitecture, PoleCropNet
from detector.crops.samples import NO_POLE, CropSet
from detector.crops.settings import CropTrainSettings
from naoslam.landmarks import CLASSES

#: Weights of the box's L1 loss (normalised crop units) and of its generalised IoU loss against the class
#: cross-entropy.
BOX_WEIGHT = 5.0
GIOU_WEIGHT = 1.0
#: Brightness is scaled by a factor drawn from this range per crop while training.
BRIGHTNESS = (0.75, 1.25)
#: With colour jitter ``j`` (``CropTrainSettings.colour_jitter``) each crop's channels are scaled by up to 1 +- j
#: (white balance), its contrast and saturation by up to 1 +- 2j, and noise of ``NOISE_PER_JITTER * j`` added.
NOISE_PER_JITTER = 0.1
#: Distillation: the temperature both networks' class scores are softened by, and the weight of the loss against
#: the teacher's scores next to the labels' (the squared temperature keeps its gradients the labels' size).
DISTIL_TEMPERATURE = 2.0
DISTIL_WEIGHT = 1.0


@dataclass(frozen=True)
class EpochResult:
    """One epoch's training loss and validation figures."""

    epoch: int
    loss: float
    pole_recall: float
    false_pole_rate: float
    box_iou: float
    seconds: float

    @property
    def score(self) -> float:
        return self.pole_recall - self.false_pole_rate


def tensors(crops: CropSet) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """A crop set as (N, 3, H, W) float 0..1, class ids and boxes."""
    images = torch.from_numpy(crops.crops).permute(0, 3, 1, 2).float().div_(255.0)
    return images, torch.from_numpy(crops.classes), torch.from_numpy(np.nan_to_num(crops.boxes))


def augment(images: torch.Tensor, boxes: torch.Tensor, generator: torch.Generator,
            colour_jitter: float = 0.0) -> tuple[torch.Tensor, torch.Tensor]:
    """Half the crops flipped left to right (with their boxes), every crop's brightness scaled; with
    ``colour_jitter``, its white balance, contrast and saturation moved and noise added too."""
    flip = torch.rand(len(images), generator=generator) < 0.5
    images, boxes = images.clone(), boxes.clone()
    images[flip] = images[flip].flip(3)
    boxes[flip] = torch.stack([1 - boxes[flip, 2], boxes[flip, 1], 1 - boxes[flip, 0], boxes[flip, 3]], dim=1)
    low, high = BRIGHTNESS
    images = images * (low + (high - low) * torch.rand(len(images), 1, 1, 1, generator=generator))
    if colour_jitter:
        images = _jitter_colour(images, colour_jitter, generator)
    return images.clamp_(0, 1), boxes


def _jitter_colour(images: torch.Tensor, jitter: float, generator: torch.Generator) -> torch.Tensor:
    """White balance (per-channel gains), contrast and saturation moved at random per crop, and pixel noise."""
    def factor(*shape: int, spread: float) -> torch.Tensor:
        return 1 + spread * (2 * torch.rand(len(images), *shape, generator=generator) - 1)

    mean = images.mean(dim=(1, 2, 3), keepdim=True)
    images = ((images - mean) * factor(1, 1, 1, spread=2 * jitter) + mean) * factor(3, 1, 1, spread=jitter)
    grey = images.mean(dim=1, keepdim=True)
    images = grey + (images - grey) * factor(1, 1, 1, spread=2 * jitter)
    return images + NOISE_PER_JITTER * jitter * torch.randn(images.shape, generator=generator)


def box_iou(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """IoU of paired boxes (N, 4) x0 y0 x1 y1."""
    inter = _intersection(a, b)
    return inter / (_area(a) + _area(b) - inter).clamp(min=1e-9)


def _intersection(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    width = (torch.minimum(a[:, 2], b[:, 2]) - torch.maximum(a[:, 0], b[:, 0])).clamp(min=0)
    height = (torch.minimum(a[:, 3], b[:, 3]) - torch.maximum(a[:, 1], b[:, 1])).clamp(min=0)
    return width * height


def _area(box: torch.Tensor) -> torch.Tensor:
    return (box[:, 2] - box[:, 0]).clamp(min=0) * (box[:, 3] - box[:, 1]).clamp(min=0)


def loss_of(outputs: torch.Tensor, classes: torch.Tensor, boxes: torch.Tensor) -> torch.Tensor:
    """Cross-entropy over the seven classes plus the weighted L1 box loss of the pole crops."""
    logits, predicted = outputs[:, :NO_POLE + 1], outputs[:, NO_POLE + 1:]
    loss = nn.functional.cross_entropy(logits, classes)
    poles = classes != NO_POLE
    if poles.any():
        loss = loss + BOX_WEIGHT * nn.functional.l1_loss(predicted[poles], boxes[poles])
        loss = loss + GIOU_WEIGHT * (1 - generalised_iou(predicted[poles], boxes[poles])).mean()
    return loss


@torch.no_grad()
def teacher_logits(teacher: PoleCropNet, images: torch.Tensor, batch: int = 1024) -> torch.Tensor:
    """The teacher's class scores (N, classes + 1) on the crops (N, 3, H, W in 0..1): the distillation targets."""
    teacher.eval()
    return torch.cat([teacher(images[i:i + batch])[:, :NO_POLE + 1] for i in range(0, len(images), batch)]) \
        if len(images) else torch.zeros((0, NO_POLE + 1))


def distillation_loss(student: torch.Tensor, teacher: torch.Tensor,
                      temperature: float = DISTIL_TEMPERATURE) -> torch.Tensor:
    """KL divergence of the student's softened class probabilities from the teacher's (both (N, classes + 1)
    logits), times the squared temperature."""
    return nn.functional.kl_div(nn.functional.log_softmax(student / temperature, dim=1),
                                nn.functional.log_softmax(teacher / temperature, dim=1), reduction="batchmean",
                                log_target=True) * temperature ** 2


def generalised_iou(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """GIoU of paired boxes (N, 4): IoU less the share of their enclosing box that neither covers, so boxes that do
    not overlap still pull together."""
    inter = _intersection(a, b)
    union = (_area(a) + _area(b) - inter).clamp(min=1e-9)
    enclosing = ((torch.maximum(a[:, 2], b[:, 2]) - torch.minimum(a[:, 0], b[:, 0])).clamp(min=0)
                 * (torch.maximum(a[:, 3], b[:, 3]) - torch.minimum(a[:, 1], b[:, 1])).clamp(min=0))
    return inter / union - (enclosing - union) / enclosing.clamp(min=1e-9)


@torch.no_grad()
def validate(network: PoleCropNet, crops: CropSet, conf: float = 0.5) -> tuple[float, float, float]:
    """Pole recall (right class, probability >= conf, box IoU >= 0.5), the share of no-pole crops taken for a pole,
    and the mean box IoU of the pole crops."""
    network.eval()
    images, classes, boxes = tensors(crops)
    outputs = torch.cat([network(images[i:i + 1024]) for i in range(0, len(images), 1024)])
    probabilities = torch.softmax(outputs[:, :NO_POLE + 1], dim=1)
    best, named = probabilities[:, :NO_POLE].max(dim=1)
    poles = classes != NO_POLE
    iou = box_iou(outputs[:, NO_POLE + 1:], boxes)
    found = poles & (named == classes) & (best >= conf) & (iou >= 0.5)
    recall = float(found.sum() / poles.sum().clamp(min=1))
    false_rate = float(((~poles) & (best >= conf)).sum() / (~poles).sum().clamp(min=1))
    return recall, false_rate, float(iou[poles].mean()) if poles.any() else 0.0


#: The fewest steps a one-cycle schedule is laid over: fewer leave its warm-up without a step (torch divides by
#: zero), as a handful of frames trained for an epoch or two would.
MIN_SCHEDULE_STEPS = 20


def one_cycle(optimiser: torch.optim.Optimizer, rate: float, steps: int) -> torch.optim.lr_scheduler.OneCycleLR:
    """The learning-rate schedule of every crop training: a tenth warming up to ``rate``, then annealing, over
    ``steps`` (at least ``MIN_SCHEDULE_STEPS``: a shorter training stops early in its schedule)."""
    return torch.optim.lr_scheduler.OneCycleLR(optimiser, rate, total_steps=max(steps, MIN_SCHEDULE_STEPS),
                                               pct_start=0.1)


def train_crop_network(train: CropSet, valid: CropSet, settings: CropTrainSettings = CropTrainSettings(),
                       start: PoleCropNet | None = None, log=print,
                       teacher: PoleCropNet | None = None) -> tuple[PoleCropNet, list[EpochResult]]:
    """Train (or go on training ``start``) on ``train``, learning ``teacher``'s class scores too where one is given;
    the best epoch on ``valid`` (or the last, as ``settings`` says) is returned with every epoch's figures."""
    torch.manual_seed(settings.seed)
    torch.set_num_threads(settings.threads)
    network = start if start is not None else PoleCropNet()
    images, classes, boxes = tensors(train)
    targets = teacher_logits(teacher, images) if teacher is not None else None
    optimiser = torch.optim.AdamW(network.parameters(), lr=settings.learning_rate, weight_decay=settings.weight_decay)
    schedule = one_cycle(optimiser, settings.learning_rate, settings.epochs * math.ceil(len(images) / settings.batch))
    generator = torch.Generator().manual_seed(settings.seed)
    best_state, best_score, history, started = None, -math.inf, [], time.perf_counter()
    for epoch in range(1, settings.epochs + 1):
        network.train()
        order, total, began = torch.randperm(len(images), generator=generator), 0.0, time.perf_counter()
        for i in range(0, len(order), settings.batch):
            batch = order[i:i + settings.batch]
            batch_images, batch_boxes = augment(images[batch], boxes[batch], generator, settings.colour_jitter)
            outputs = network(batch_images)
            loss = loss_of(outputs, classes[batch], batch_boxes)
            if targets is not None:
                loss = loss + DISTIL_WEIGHT * distillation_loss(outputs[:, :NO_POLE + 1], targets[batch])
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
            schedule.step()
            total += loss.item() * len(batch)
        recall, false_rate, iou = validate(network, valid)
        result = EpochResult(epoch, total / len(images), recall, false_rate, iou, time.perf_counter() - began)
        history.append(result)
        log(f"epoch {epoch}/{settings.epochs}: loss {result.loss:.4f}, valid pole recall {recall:.3f}, "
            f"false poles {false_rate:.4f}, box IoU {iou:.3f} ({result.seconds:.0f} s)")
        if result.score > best_score or settings.keep == "last":
            best_score, best_state = result.score, {k: v.clone() for k, v in network.state_dict().items()}
        if settings.minutes is not None and time.perf_counter() - started > 60 * settings.minutes:
            log(f"stopped after {epoch} epochs: the {settings.minutes:.1f} minutes are spent")
            break
    network.load_state_dict(best_state)
    return network.eval(), history


def save_checkpoint(network: PoleCropNet, path: Path, history: list[EpochResult], settings: CropTrainSettings) -> Path:
    """The network, its shape and how it was trained, as one torch file (written atomically)."""
    checkpoint = {"kind": "pole-crops", "classes": list(CLASSES), **network.architecture.to_dict(),
                  "state": network.state_dict(),
                  "settings": asdict(settings), "history": [asdict(h) for h in history]}
    with atomic_path(path) as tmp:
        torch.save(checkpoint, tmp)
    return Path(path)


def load_checkpoint(path: Path, option: str = "--weights") -> PoleCropNet:
    """A crop network saved by :func:`save_checkpoint`; ValueError naming the file for anything else (a missing one
    says to leave out ``option``, the flag that named it)."""
    if not Path(path).is_file():
        raise FileNotFoundError(f"{path}: no such checkpoint - pass a poles-robot.pt written by `poles train-robot` "
                                f"(or leave out {option}{' to train from scratch' if option == '--weights' else ''})")
    try:
        checkpoint = torch.load(str(path), map_location="cpu", weights_only=False)
    except Exception as error:  # pickle, zip and runtime errors of files that are not checkpoints
        raise ValueError(f"{path}: not a readable PyTorch checkpoint ({type(error).__name__}) - pass a "
                         "poles-robot.pt written by `poles train-robot`") from None
    if not isinstance(checkpoint, dict) or checkpoint.get("kind") != "pole-crops":
        raise ValueError(f"{path}: not a crop network checkpoint - pass a poles-robot.pt written by "
                         "`poles train-robot`")
    network = PoleCropNet(CropArchitecture.from_dict(checkpoint))
    network.load_state_dict(checkpoint["state"])
    return network.eval()
