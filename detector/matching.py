"""Box and mask IoU, the box around a mask, and greedy one-to-one matching of detections to references (best score first)."""
from __future__ import annotations

import numpy as np


def box_iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """IoU matrix (len(a), len(b)) of xyxy boxes."""
    a = np.asarray(a, dtype=float).reshape(-1, 4)
    b = np.asarray(b, dtype=float).reshape(-1, 4)
    top_left = np.maximum(a[:, None, :2], b[None, :, :2])
    bottom_right = np.minimum(a[:, None, 2:], b[None, :, 2:])
    inter = np.prod(np.clip(bottom_right - top_left, 0, None), axis=2)
    area_a = np.prod(a[:, 2:] - a[:, :2], axis=1)
    area_b = np.prod(b[:, 2:] - b[:, :2], axis=1)
    union = area_a[:, None] + area_b[None, :] - inter
    return np.divide(inter, union, out=np.zeros_like(inter), where=union > 0)


def mask_iou(a: list[np.ndarray] | np.ndarray, b: list[np.ndarray] | np.ndarray) -> np.ndarray:
    """IoU matrix of boolean masks of one frame size (two empty masks have IoU 0)."""
    if len(a) == 0 or len(b) == 0:
        return np.zeros((len(a), len(b)))
    fa = np.asarray(a, dtype=bool).reshape(len(a), -1).astype(np.float32)
    fb = np.asarray(b, dtype=bool).reshape(len(b), -1).astype(np.float32)
    inter = fa @ fb.T
    union = fa.sum(1)[:, None] + fb.sum(1)[None, :] - inter
    return np.divide(inter, union, out=np.zeros_like(inter), where=union > 0).astype(float)


def mask_box(mask: np.ndarray) -> tuple[float, float, float, float]:
    """The box (x0, y0, x1, y1, pixel edges) around a mask; all zero for an empty one."""
    rows, columns = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    if not len(rows):
        return (0.0, 0.0, 0.0, 0.0)
    return (float(columns[0]), float(rows[0]), float(columns[-1] + 1), float(rows[-1] + 1))


def greedy_match(iou: np.ndarray, scores: np.ndarray, threshold: float,
                 allowed: np.ndarray | None = None) -> list[tuple[int, int]]:
    """Pairs (prediction, reference): predictions in descending score take the free reference of highest IoU.

    ``iou`` is (predictions, references); a pair needs IoU >= ``threshold`` and ``allowed[p, r]`` (e.g. same class).
    """
    iou = np.where(allowed, iou, -1.0) if allowed is not None else np.array(iou, dtype=float)
    taken: set[int] = set()
    pairs = []
    for p in np.argsort(-np.asarray(scores), kind="stable"):
        if iou.shape[1] == 0:
            break
        row = iou[p].copy()
        row[list(taken)] = -1.0
        r = int(np.argmax(row))
        if row[r] >= threshold:
            taken.add(r)
            pairs.append((int(p), r))
    return pairs
