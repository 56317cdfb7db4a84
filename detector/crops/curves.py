"""The crop network's training curves: loss, and on the valid crops pole recall, false poles and box IoU, per epoch."""
from __future__ import annotations

from pathlib import Path

from detector.crops.train import EpochResult
from detector.figures import plt, save_figure


def plot_crop_history(history: list[EpochResult], png: Path) -> Path:
    """Training loss and the validation figures per epoch, the kept (best) epoch dotted."""
    epochs = [h.epoch for h in history]
    best = max(history, key=lambda h: h.score).epoch
    fig, (left, right) = plt.subplots(1, 2, figsize=(9, 3.4), constrained_layout=True)
    left.plot(epochs, [h.loss for h in history], marker=".")
    left.set_title("training loss (classes + 5 x box L1)")
    for label, values in (("pole recall (right class, IoU >= 0.5)", [h.pole_recall for h in history]),
                          ("no-pole crops taken for poles", [h.false_pole_rate for h in history]),
                          ("mean box IoU", [h.box_iou for h in history])):
        right.plot(epochs, values, marker=".", label=label)
    right.set_title("valid crops")
    right.set_ylim(0, 1)
    right.legend(fontsize=7)
    for ax in (left, right):
        ax.axvline(best, color="grey", linestyle=":", linewidth=1)
        ax.set_xlabel("epoch")
        ax.grid(alpha=0.3)
    fig.suptitle(f"crop network (kept epoch {best} of {len(epochs)}, dotted)")
    return save_figure(fig, png)
