"""Recall by a pole's width in pixels: how small a pole a front end still finds (far poles are a few px wide)."""
from __future__ import annotations

from detector.evaluation.counting import ImageEvaluation, label_width_px
from detector.evaluation.results import WidthRecall

__all__ = ["WIDTH_EDGES_PX", "label_width_px", "recall_by_width", "width_bin_names"]

#: Bin edges (px at 640 px frame width): far poles (< 10 px, about 5 m and beyond on a Nao), 10-16, 16-32, 32-64, near.
WIDTH_EDGES_PX = (10, 16, 32, 64)


def width_bin_names() -> list[str]:
    """Readable names of the bins, smallest first ("< 10 px", "10-16 px", ..., ">= 64 px")."""
    edges = WIDTH_EDGES_PX
    return ([f"< {edges[0]} px"] + [f"{lo}-{hi} px" for lo, hi in zip(edges, edges[1:])] + [f">= {edges[-1]} px"])


def recall_by_width(images: list[ImageEvaluation], conf: float) -> list[WidthRecall]:
    """Labels and labels found (a true positive at ``conf``) in each width bin."""
    names = width_bin_names()
    labels, found = [0] * len(names), [0] * len(names)
    for image in images:
        matched = {r for _, r in image.match(conf)}
        for r, width in enumerate(image.truth_widths):
            bin_index = sum(width >= edge for edge in WIDTH_EDGES_PX)
            labels[bin_index] += 1
            found[bin_index] += r in matched
    return [WidthRecall(name, n, k) for name, n, k in zip(names, labels, found)]
