"""What a training run hands on: its weights, its curves and, for a YOLOv8 run, its best validation epoch."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from detector.records import JsonRecord


@dataclass(frozen=True)
class BestEpoch(JsonRecord):
    """The epoch with the highest validation fitness (the one Ultralytics keeps as best.pt) and its figures."""

    epoch: int
    #: Epochs the run trained.
    epochs: int
    box_map50: float
    box_map50_95: float
    mask_map50: float
    mask_map50_95: float
    #: Validation losses at that epoch, by Ultralytics' names (box_loss, seg_loss, cls_loss, dfl_loss).
    losses: dict[str, float]


@dataclass(frozen=True)
class TrainingSummary(JsonRecord):
    """A finished training: the network, what it started from, the weights it hands on and how it went."""

    model: str
    #: The checkpoint it started from (None: from scratch).
    started_from: Path | None
    weights: Path
    curves: Path
    epochs: int
    #: The time cap it trained under (None: it trained for its epochs).
    minutes: float | None = None
    #: A YOLOv8 run's best validation epoch (the crop network keeps no such record).
    best: BestEpoch | None = None
