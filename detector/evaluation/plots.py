"""Pictures of an evaluation: counts per image (thesis figure 4.10), the confidence sweep, recall by pole width,
FP/FN overlays."""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from matplotlib.ticker import MaxNLocator

from detector.evaluation.counting import ImageEvaluation, best_threshold
from detector.evaluation.results import FrameCounts, SweepPoint, WidthRecall
from detector.figures import plt, save_figure
from detector.preview import draw_label
from detector.atomic import write_bytes
from naoslam.perception.detections import Detection

COUNT_COLOURS = {"tp": "#2ca02c", "fp": "#d62728", "fn": "#ff7f0e", "tn": "#1f77b4"}
#: BGR colours of the overlays: matched detections, false positives, missed labels.
TP_BGR, FP_BGR, FN_BGR = (255, 160, 0), (0, 0, 255), (0, 220, 255)
#: Up to this many images, the per-image bars are labelled with the images' names.
MAX_NAMED_IMAGES = 40
#: Characters of an image's name shown under its bar (Roboflow's names run to 60 and more, taller than the figure).
NAME_CHARACTERS = 24


def plot_per_image(per_image: tuple[FrameCounts, ...], png: Path, title: str) -> Path:
    """Stacked bars of TP, FP, FN and TN for every image, named when there are few."""
    fig, ax = plt.subplots(figsize=(max(6, 0.12 * len(per_image) + 2), 3.2), constrained_layout=True)
    x = np.arange(len(per_image))
    bottom = np.zeros(len(per_image))
    for key, colour in COUNT_COLOURS.items():
        values = np.array([getattr(row.counts, key) for row in per_image])
        ax.bar(x, values, bottom=bottom, color=colour, label=key.upper(), width=0.9)
        bottom += values
    if len(per_image) <= MAX_NAMED_IMAGES:
        ax.set_xticks(x, [_short_name(Path(row.image).stem) for row in per_image], rotation=90, fontsize=7)
    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_ylim(0, bottom.max(initial=0) + 1)  # headroom for the legend
    ax.set_xlabel("image")
    ax.set_ylabel("count")
    ax.set_title(f"{title}: per-image counts")
    ax.legend(ncol=4, fontsize=8)
    return save_figure(fig, png)


def _short_name(stem: str) -> str:
    """An image's name cut to ``NAME_CHARACTERS``: its start and its end, which tell Roboflow's names apart."""
    if len(stem) <= NAME_CHARACTERS:
        return stem
    half = (NAME_CHARACTERS - 1) // 2
    return f"{stem[:half]}…{stem[-half:]}"


def plot_sweep(sweep: tuple[SweepPoint, ...], png: Path, title: str) -> Path:
    """Precision, recall and F1 against the confidence threshold."""
    fig, ax = plt.subplots(figsize=(5, 3.2), constrained_layout=True)
    conf = [point.conf for point in sweep]
    for key in ("precision", "recall", "f1"):
        ax.plot(conf, [getattr(point, key) for point in sweep], label=key)
    best = best_threshold(sweep)
    if best is not None:
        ax.axvline(best, color="grey", linestyle=":", label=f"best F1 at {best:.2f}")
    else:
        ax.text(0.5, 0.75, "one score for every detection:\nthe threshold changes nothing", transform=ax.transAxes,
                ha="center", va="center", fontsize=9, color="0.3")
    ax.set_title(f"{title}: confidence sweep")
    ax.set_xlabel("confidence threshold")
    ax.set_ylim(0, 1.02)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    return save_figure(fig, png)


def plot_recall_by_width(rows: tuple[WidthRecall, ...], png: Path, title: str) -> Path:
    """Recall in each pole-width bin as bars, each labelled with found / labels."""
    fig, ax = plt.subplots(figsize=(5, 3.2), constrained_layout=True)
    x = np.arange(len(rows))
    recall = [row.recall or 0.0 for row in rows]
    ax.bar(x, recall, color=COUNT_COLOURS["tp"], width=0.7)
    for i, row in enumerate(rows):
        ax.text(i, recall[i] + 0.02, f"{row.found}/{row.labels}", ha="center", fontsize=8)
    ax.set_xticks(x, [row.width for row in rows], fontsize=8)
    ax.set_xlabel("pole width (rotated box, px in a 640 px wide frame)")
    ax.set_ylabel("recall")
    ax.set_ylim(0, 1.12)
    ax.set_title(f"{title}: recall by pole width")
    ax.grid(alpha=0.3, axis="y")
    return save_figure(fig, png)


def plot_confusion(matrix: np.ndarray, classes: tuple[str, ...], png: Path, title: str) -> Path:
    """The confusion matrix as a grid of counts: true class down, detected class across, "none" last."""
    labels = [*classes, "none"]
    fig, ax = plt.subplots(figsize=(4.6, 4.0), constrained_layout=True)
    shown = np.ma.masked_equal(matrix, 0)
    ax.imshow(shown, cmap="Blues")
    for (row, col), count in np.ndenumerate(matrix):
        if count:
            dark = count > 0.6 * matrix.max()
            ax.text(col, row, str(count), ha="center", va="center", fontsize=8, color="white" if dark else "black")
    ax.set_xticks(range(len(labels)), labels)
    ax.set_yticks(range(len(labels)), labels)
    ax.set_xlabel("detected (none: missed)")
    ax.set_ylabel("true (none: no pole there)")
    ax.set_title(f"{title}: confusion", fontsize=9)
    return save_figure(fig, png)


def _outline(image: np.ndarray, mask: np.ndarray, colour, text: str) -> None:
    contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    cv2.drawContours(image, contours, -1, colour, 2)
    if contours:
        x, y, _, _ = cv2.boundingRect(np.concatenate(contours))
        draw_label(image, text, (x, max(12, y - 4)), colour)


def write_overlay(image: ImageEvaluation, frame: np.ndarray, detections: list[Detection],
                  truth_masks: list[np.ndarray], conf: float, folder: Path) -> bool:
    """``folder/<image>.jpg`` when the image has a false positive or a false negative at ``conf``: the frame with
    found, wrong and missed poles outlined (``detections`` with their masks, ``truth_masks``: the labels'). Returns
    whether it was written."""
    counts = image.counts(conf)
    if not counts.fp and not counts.fn:
        return False
    frame = frame.copy()
    pairs = image.match(conf)
    matched_p, matched_r = {p for p, _ in pairs}, {r for _, r in pairs}
    for p in image.kept(conf):
        colour, detection = TP_BGR if p in matched_p else FP_BGR, detections[p]
        _outline(frame, detection.full_mask(frame.shape), colour, f"{detection.name} {detection.confidence:.2f}")
        if detection.band_centres is not None:
            cv2.drawMarker(frame, tuple(int(v) for v in detection.divide_centre), colour, cv2.MARKER_CROSS, 12, 2)
    for r, (cls, mask) in enumerate(zip(image.truth_classes, truth_masks)):
        if r not in matched_r:
            _outline(frame, mask, FN_BGR, f"missed {cls}")
    ok, encoded = cv2.imencode(".jpg", frame, [cv2.IMWRITE_JPEG_QUALITY, 85])
    write_bytes(folder / image.name, encoded.tobytes())
    return True
