"""Loss and metric curves of a training run (like the thesis's figures 3.8-3.10) and its best epoch."""
from __future__ import annotations

import csv
from pathlib import Path

from detector.figures import plt, save_figure
from detector.training.summary import BestEpoch

LOSSES = ("box_loss", "seg_loss", "cls_loss", "dfl_loss")
METRICS = ("mAP50(B)", "mAP50-95(B)", "mAP50(M)", "mAP50-95(M)")


def read_results(csv_path: Path) -> dict[str, list[float]]:
    """Columns of Ultralytics' results.csv as float lists (header names stripped)."""
    path = Path(csv_path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no results.csv - the run did not finish an epoch")
    with path.open(newline="") as handle:
        rows = list(csv.DictReader(handle))
    if not rows:
        raise ValueError(f"{path}: results.csv has no epochs")
    return {key.strip(): [float(row[key]) for row in rows] for key in rows[0]}


def fitness(columns: dict[str, list[float]], i: int) -> float:
    """Ultralytics' segmentation fitness: 0.1 mAP50 + 0.9 mAP50-95 for boxes plus the same for masks."""
    return sum(0.1 * columns[f"metrics/mAP50({k})"][i] + 0.9 * columns[f"metrics/mAP50-95({k})"][i] for k in "BM")


def best_epoch(csv_path: Path) -> BestEpoch:
    """The epoch with the highest validation fitness (the one Ultralytics keeps as best.pt) and its metrics."""
    columns = read_results(csv_path)
    i = max(range(len(columns["epoch"])), key=lambda j: fitness(columns, j))
    box_map50, box_map50_95, mask_map50, mask_map50_95 = (columns[f"metrics/{m}"][i] for m in METRICS)
    return BestEpoch(int(columns["epoch"][i]), len(columns["epoch"]), box_map50, box_map50_95, mask_map50,
                     mask_map50_95, {loss: columns[f"val/{loss}"][i] for loss in LOSSES})


def plot_training_curves(csv_path: Path, png: Path) -> Path:
    """Train and validation losses per epoch, and validation mAP, with the best epoch marked."""
    columns = read_results(csv_path)
    best = best_epoch(csv_path).epoch
    epochs = columns["epoch"]
    fig, axes = plt.subplots(1, len(LOSSES) + 1, figsize=(4 * (len(LOSSES) + 1), 3.4), constrained_layout=True)
    for ax, loss in zip(axes, LOSSES):
        ax.plot(epochs, columns[f"train/{loss}"], label="train", marker="." if len(epochs) < 30 else None)
        ax.plot(epochs, columns[f"val/{loss}"], label="validation", marker="." if len(epochs) < 30 else None)
        ax.set_title(loss.replace("_", " "))
    for metric in METRICS:
        axes[-1].plot(epochs, columns[f"metrics/{metric}"], label=metric)
    axes[-1].set_title("validation mAP")
    axes[-1].set_ylim(0, 1)
    for ax in axes:
        ax.axvline(best, color="grey", linestyle=":", linewidth=1)
        ax.set_xlabel("epoch")
        ax.legend(fontsize=7)
        ax.grid(alpha=0.3)
    fig.suptitle(f"training curves (best epoch {best} of {len(epochs)}, dotted)")
    return save_figure(fig, png)
