"""Error statistics, pose consistency (NEES) and the rigid SE(2) alignment used to score a map without robot truth."""
from __future__ import annotations

import math

import numpy as np

from naoslam.motion import wrap


def error_stats(errors: np.ndarray) -> dict[str, float]:
    """Mean, standard deviation and RMSE (same unit as ``errors``)."""
    e = np.asarray(errors, dtype=float)
    return {"mean": float(e.mean()), "std": float(e.std()), "rmse": float(np.sqrt(np.mean(e ** 2)))}


def pose_nees(pose: np.ndarray, pose_cov: np.ndarray, true_pose: np.ndarray) -> float:
    """Normalised estimation error squared of a pose (x, y, theta) with covariance ``pose_cov`` (3 degrees of freedom)."""
    error = np.asarray(pose, dtype=float) - true_pose
    error[2] = wrap(error[2])
    return float(error @ np.linalg.solve(pose_cov, error))


def fit_se2(points: np.ndarray, reference: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rotation matrix and translation (no scale) that best fit ``points`` onto ``reference`` (Kabsch):
    ``points @ rotation.T + translation``."""
    p, q = np.asarray(points, float), np.asarray(reference, float)
    p_mean, q_mean = p.mean(axis=0), q.mean(axis=0)
    u, _, vt = np.linalg.svd((p - p_mean).T @ (q - q_mean))
    d = np.sign(np.linalg.det(vt.T @ u.T))
    rotation = vt.T @ np.diag([1.0, d]) @ u.T
    return rotation, q_mean - p_mean @ rotation.T


def chi2_cdf(x: float, dof: int) -> float:
    """P(X <= x) for X ~ chi-square with integer ``dof`` (closed forms; no scipy on the robot)."""
    if x <= 0:
        return 0.0
    half = x / 2
    if dof % 2 == 0:
        term, total = 1.0, 1.0
        for i in range(1, dof // 2):
            term *= half / i
            total += term
        return 1.0 - math.exp(-half) * total
    root = math.sqrt(x)
    term, total = root, 0.0
    for r in range(1, (dof - 1) // 2 + 1):  # x^((2r-1)/2) / (1 * 3 * ... * (2r-1))
        total += term
        term *= x / (2 * r + 1)
    return math.erf(root / math.sqrt(2)) - 2 * math.exp(-half) / math.sqrt(2 * math.pi) * total


def chi2_band(dof: int, runs: int = 1) -> tuple[float, float]:
    """95 % band of the average of ``runs`` chi-square(``dof``) samples: where a consistent filter's average NEES
    (or NIS) over ``runs`` Monte Carlo runs falls 95 % of the time (Bar-Shalom)."""
    k = dof * runs

    def quantile(p: float) -> float:
        low, high = 0.0, k + 20.0 * math.sqrt(k) + 20.0
        for _ in range(100):
            middle = (low + high) / 2
            low, high = (middle, high) if chi2_cdf(middle, k) < p else (low, middle)
        return (low + high) / 2 / runs

    return quantile(0.025), quantile(0.975)
