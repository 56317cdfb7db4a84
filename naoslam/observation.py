"""Range-bearing observation of a point landmark from a planar pose, its Jacobians and its inverse."""
from __future__ import annotations

import math

import numpy as np

from naoslam.motion import wrap

#: 99 % point of the chi-square distribution with 2 degrees of freedom: the default validation gate.
CHI2_2DOF_99 = 9.21


def check_gate(gate: float | None) -> None:
    """Refuse a validation gate that would turn every measurement away (None: no gate)."""
    if gate is not None and not 0 < gate < math.inf:
        raise ValueError(f"gate {gate} must be a positive chi-square bound (e.g. 9.21)")


def expected(pose: np.ndarray, landmark: np.ndarray) -> np.ndarray:
    """Predicted (range, bearing) of ``landmark`` (x, y) seen from ``pose`` (x, y, theta)."""
    dx, dy = landmark[0] - pose[0], landmark[1] - pose[1]
    return np.array([math.hypot(dx, dy), float(wrap(math.atan2(dy, dx) - pose[2]))])


def jacobians(pose: np.ndarray, landmark: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """d(range, bearing)/d pose (2x3) and d(range, bearing)/d landmark (2x2)."""
    dx, dy = landmark[0] - pose[0], landmark[1] - pose[1]
    q = max(dx * dx + dy * dy, 1e-12)
    r = math.sqrt(q)
    h_landmark = np.array([[dx / r, dy / r], [-dy / q, dx / q]])
    h_pose = np.array([[-dx / r, -dy / r, 0.0], [dy / q, -dx / q, -1.0]])
    return h_pose, h_landmark


def innovation(z: np.ndarray, predicted: np.ndarray) -> np.ndarray:
    """Measurement minus prediction with the bearing difference wrapped."""
    return np.array([z[0] - predicted[0], float(wrap(z[1] - predicted[1]))])


def landmark_from(pose: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Landmark position seen at (range, bearing) from ``pose``, with its Jacobians wrt pose (2x3) and z (2x2)."""
    r, phi = z
    heading = pose[2] + phi
    c, s = math.cos(heading), math.sin(heading)
    position = np.array([pose[0] + r * c, pose[1] + r * s])
    j_pose = np.array([[1.0, 0.0, -r * s], [0.0, 1.0, r * c]])
    j_z = np.array([[c, -r * s], [s, r * c]])
    return position, j_pose, j_z


def noise(range_std: float, bearing_std: float) -> np.ndarray:
    """Measurement covariance Q."""
    return np.diag([range_std ** 2, bearing_std ** 2])
