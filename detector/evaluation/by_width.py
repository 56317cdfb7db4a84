"""Recall by a pole's width in pixels: how small a pole a front end still finds (far poles are a few px wide)."""
from __future__ import annotations

import numpy as np

from detector.evaluation.counting import ImageEvaluation
from naoslam.detector import rotated_box_of_mask

#: Widths are given for a frame 640 px wide (the Nao's), so a 1280x960 frame's poles count at half their width.
REFERENCE_FRAME_WIDTH_PX = 640
#: Bin edges (px at 640 px frame width): far poles (< 10 px, about 5 m and beyond on a Nao), 10-16, 16-32, 32-64, near.
WIDTH_EDGES_PX = (10, 16, 32, 64)


def label_width_px(mask: np.ndarray) -> float:
    """The label's width: the short side of the rotated box around its mask, scaled to a 640 px wide frame."""
    box = rotated_box_of_mask(mask)
    return 0.0 if box is None else box.width * REFERENCE_FRAME_WIDTH_PX / mask.shape[1]


def width_bin_names() -> list[str]:
    """Readable names of the bins, smallest first ("< 10 px", "10-16 px", ..., ">= 64 px")."""
    edges = WIDTH_EDGES_PX
    return ([f"< {edges[0]} px"] + [f"{lo}-{hi} px" for lo, hi in zip(edges, edges[1:])] + [f">= {edges[-1]} px"])


def recall_by_width(images: list[ImageEvaluation], conf: float) -> list[dict]:
    """Labels, labels found (a true positive at ``conf``) and recall in each width bin; recall None for an empty bin."""
    names = width_bin_names()
    labels, found = [0] * len(names), [0] * len(names)
    for image in images:
        matched = {r for _, r in image.match(conf)}
        for r, mask in enumerate(image.truth_masks):
            bin_index = sum(label_width_px(mask) >= edge for edge in WIDTH_EDGES_PX)
            labels[bin_index] += 1
            found[bin_index] += r in matched
    return [{"width": name, "labels": n, "found": k, "recall": k / n if n else None}
            for name, n, k in zip(names, labels, found)]
