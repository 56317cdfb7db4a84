"""Error statistics and the rigid SE(2) alignment used to score a map without robot truth."""
from __future__ import annotations

import numpy as np


def error_stats(errors: np.ndarray) -> dict[str, float]:
    """Mean, standard deviation and RMSE (same unit as ``errors``)."""
    e = np.asarray(errors, dtype=float)
    return {"mean": float(e.mean()), "std": float(e.std()), "rmse": float(np.sqrt(np.mean(e ** 2)))}


def align_se2(points: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """``points`` moved by the rotation and translation (no scale) that best fit them onto ``reference`` (Kabsch)."""
    p, q = np.asarray(points, float), np.asarray(reference, float)
    p_mean, q_mean = p.mean(axis=0), q.mean(axis=0)
    u, _, vt = np.linalg.svd((p - p_mean).T @ (q - q_mean))
    d = np.sign(np.linalg.det(vt.T @ u.T))
    rotation = vt.T @ np.diag([1.0, d]) @ u.T
    return (p - p_mean) @ rotation.T + q_mean
