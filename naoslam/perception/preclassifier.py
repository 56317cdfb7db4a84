"""The robot front end's preclassifier: a network of a few thousand parameters that scores a small crop (12x24) of
every candidate window before the crop network sees any, so a cluttered frame's dozens of windows cost a few
crop-network passes, not dozens.

It travels inside the crop network's ONNX file: the naoslam metadata's ``preclassifier`` entry holds its ONNX graph
(base64), the threshold it was chosen at (the highest that keeps 99 % of the valid poles the crop network names;
``detector.crops.preclassifier``) and what it kept and rejected there. A crop network without the entry runs every
window, as before.
"""
from __future__ import annotations

import base64
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import onnxruntime as ort

from naoslam.perception.engines import BatchNetwork

#: The metadata entry, and the graph's input name.
PRECLASSIFIER_KEY = "preclassifier"
PRECLASSIFIER_INPUT = "crops"
#: Most windows of one frame the crop network sees after the preclassifier (its best scored); a frame with more
#: passing windows is said to hit the budget (``CropDetector.cost``).
WINDOW_BUDGET = 8


def preclassifier_entry(graph: bytes, threshold: float, kept_poles: float, rejected_clutter: float) -> dict:
    """The metadata entry that carries a preclassifier in a crop network's file."""
    return {"onnx": base64.b64encode(graph).decode("ascii"), "threshold": float(threshold),
            "kept_poles": float(kept_poles), "rejected_clutter": float(rejected_clutter)}


@dataclass(frozen=True)
class FrameCost:
    """What one frame cost the two-stage front end: the finder's windows, those the crop network looked at, its
    second looks, and whether more windows passed the preclassifier than ``WINDOW_BUDGET``."""

    windows: int = 0
    looked_at: int = 0
    second_looks: int = 0
    hit_budget: bool = False


class Preclassifier:
    """The preclassifier stored in a crop network's metadata, ready to score crops."""

    def __init__(self, entry: dict, source: Path | str, threads: int | None = None, engine: str = "onnxruntime"):
        from naoslam.perception.pole_model import session_options  # the one place sessions are set up

        try:
            graph = base64.b64decode(entry["onnx"])
            self.threshold = float(entry["threshold"])
            session = ort.InferenceSession(graph, session_options(threads), providers=["CPUExecutionProvider"])
        except Exception as error:  # base64, key and onnxruntime errors of a damaged entry
            raise ValueError(f"{source}: the preclassifier stored in the model is damaged ({type(error).__name__}) "
                             "- export the model again with `poles train-robot`") from None
        self.network = BatchNetwork(session, graph, engine, threads)
        height, width = session.get_inputs()[0].shape[2:]
        #: The crop (width, height) it looks at.
        self.size_wh = (int(width), int(height))

    def scores(self, blob: np.ndarray) -> np.ndarray:
        """The probability that each crop (N, 3, H, W) holds a pole."""
        return self.network(blob)[:, 0]

    def chosen(self, blob: np.ndarray, budget: int = WINDOW_BUDGET) -> tuple[np.ndarray, bool]:
        """The crops worth the crop network's look (indices, best scored first, at most ``budget``) and whether more
        than ``budget`` passed the threshold."""
        scores = self.scores(blob)
        passed = np.flatnonzero(scores >= self.threshold)
        ordered = passed[np.argsort(-scores[passed], kind="stable")]
        return ordered[:budget], len(passed) > budget
