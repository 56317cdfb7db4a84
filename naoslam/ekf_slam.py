"""EKF SLAM with known correspondences (the landmark class is its signature), and its variants.

State: pose (x, y, theta) followed by (x, y) of each landmark in the order they entered the map. Updates touch
only the pose and the observed landmark's blocks through index slices: O(n) for the gain and O(n^2) for the
covariance product. Variants, combinable (2024 thesis, 3.2):
- outlier filter: drop a measurement whose range differs more than 0.4 m or bearing more than pi/3 from prediction;
- validation gate (beyond the thesis): drop it when its squared Mahalanobis distance exceeds a chi-square bound;
- minimal view: a landmark enters the map only after ``min_views`` sightings that agree in position;
- FEJ-EKF (Huang, Mourikis and Roumeliotis): the motion Jacobian uses the displacement from the previous
  *predicted* pose, and the landmark part of H (and its pose part) the landmark's first estimate.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from naoslam import observation
from naoslam.measurement import Measurement
from naoslam.motion import OdometryModel, VelocityModel, wrap

OUTLIER_RANGE_M = 0.4
OUTLIER_BEARING_RAD = math.pi / 3


@dataclass(frozen=True)
class SlamConfig:
    """Which variant to run. ``gate``: chi-square bound (2 dof) or None; ``min_views``: 1 = classic."""

    fej: bool = False
    outlier_filter: bool = False
    gate: float | None = None
    min_views: int = 1
    min_view_radius_m: float = 0.5

    def __post_init__(self) -> None:
        if self.min_views < 1:
            raise ValueError(f"--min-views {self.min_views} must be at least 1")
        if self.gate is not None and self.gate <= 0:
            raise ValueError(f"--gate {self.gate} must be a positive chi-square bound (e.g. 9.21)")

    @property
    def label(self) -> str:
        parts = ["FEJ-EKF" if self.fej else "EKF"]
        if self.outlier_filter:
            parts.append("outlier filter")
        if self.gate:
            parts.append(f"gate {self.gate:g}")
        if self.min_views > 1:
            parts.append(f"min view {self.min_views}")
        return " + ".join(parts)


@dataclass
class UpdateLog:
    """What happened to each measurement of one update."""

    accepted: list[str] = field(default_factory=list)
    initialised: list[str] = field(default_factory=list)
    pending: list[str] = field(default_factory=list)
    rejected: list[str] = field(default_factory=list)


class EkfSlam:
    """EKF SLAM over a pose and a growing map of signed point landmarks."""

    def __init__(self, pose: np.ndarray, pose_cov: np.ndarray, motion: OdometryModel | VelocityModel,
                 config: SlamConfig = SlamConfig()):
        self.mu = np.asarray(pose, dtype=float).copy()
        self.sigma = np.asarray(pose_cov, dtype=float).copy()
        self.motion = motion
        self.config = config
        self.slots: dict[str, int] = {}
        self.first_estimates: dict[str, np.ndarray] = {}
        self.sightings: dict[str, list[np.ndarray]] = {}
        self._previous_predicted = self.mu[:3].copy()

    @property
    def pose(self) -> np.ndarray:
        return self.mu[:3]

    @property
    def landmarks(self) -> dict[str, np.ndarray]:
        """Estimated landmark positions by signature."""
        return {sig: self.mu[i:i + 2].copy() for sig, i in self.slots.items()}

    def predict(self, u: np.ndarray) -> None:
        """Move the pose with control ``u``; the pose-landmark cross covariances follow through G."""
        pose = self.mu[:3].copy()
        g, v = self.motion.jacobians(pose, u)
        self.mu[:3] = self.motion.move(pose, u)
        if self.config.fej:
            # Huang et al.: linearise at the previous *predicted* pose, not the updated one.
            dx, dy = self.mu[:3][:2] - self._previous_predicted[:2]
            g = np.array([[1.0, 0.0, -dy], [0.0, 1.0, dx], [0.0, 0.0, 1.0]])
        self._previous_predicted = self.mu[:3].copy()
        sigma = self.sigma
        sigma[:3, :3] = g @ sigma[:3, :3] @ g.T + v @ self.motion.control_noise(u) @ v.T
        sigma[:3, 3:] = g @ sigma[:3, 3:]
        sigma[3:, :3] = sigma[:3, 3:].T

    def update(self, measurements: list[Measurement]) -> UpdateLog:
        """Fold in one frame's measurements, one landmark at a time."""
        log = UpdateLog()
        for m in measurements:
            z = np.array([m.range_m, m.bearing_rad])
            q = observation.noise(m.range_std, m.bearing_std)
            if m.signature in self.slots:
                (log.accepted if self._correct(m.signature, z, q) else log.rejected).append(m.signature)
            elif self._seen_enough(m.signature, z):
                self._add_landmark(m.signature, z, q)
                log.initialised.append(m.signature)
            else:
                log.pending.append(m.signature)
        return log

    def _seen_enough(self, signature: str, z: np.ndarray) -> bool:
        """Minimal view: true on the n-th sighting in agreeing places (a far-off sighting restarts the count)."""
        if self.config.min_views <= 1:
            return True
        position = observation.landmark_from(self.pose, z)[0]
        seen = self.sightings.setdefault(signature, [])
        if seen and np.linalg.norm(position - np.mean(seen, axis=0)) > self.config.min_view_radius_m:
            seen.clear()
        seen.append(position)
        if len(seen) >= self.config.min_views:
            del self.sightings[signature]
            return True
        return False

    def _add_landmark(self, signature: str, z: np.ndarray, q: np.ndarray) -> None:
        position, j_pose, j_z = observation.landmark_from(self.pose, z)
        n = len(self.mu)
        cross = j_pose @ self.sigma[:3, :]
        sigma = np.zeros((n + 2, n + 2))
        sigma[:n, :n] = self.sigma
        sigma[n:, :n] = cross
        sigma[:n, n:] = cross.T
        sigma[n:, n:] = j_pose @ self.sigma[:3, :3] @ j_pose.T + j_z @ q @ j_z.T
        self.sigma = sigma
        self.mu = np.concatenate([self.mu, position])
        self.slots[signature] = n
        self.first_estimates[signature] = position.copy()

    def _correct(self, signature: str, z: np.ndarray, q: np.ndarray) -> bool:
        j = self.slots[signature]
        landmark = self.mu[j:j + 2]
        nu = observation.innovation(z, observation.expected(self.pose, landmark))
        at = self.first_estimates[signature] if self.config.fej else landmark
        h_pose, h_landmark = observation.jacobians(self.pose, at)
        idx = np.r_[0:3, j:j + 2]
        h = np.hstack([h_pose, h_landmark])
        sigma_cols = self.sigma[:, idx]
        s = h @ sigma_cols[idx] @ h.T + q
        if self.config.outlier_filter and (abs(nu[0]) > OUTLIER_RANGE_M or abs(nu[1]) > OUTLIER_BEARING_RAD):
            return False
        s_inv = np.linalg.inv(s)
        if self.config.gate is not None and float(nu @ s_inv @ nu) > self.config.gate:
            return False
        k = sigma_cols @ h.T @ s_inv
        self.mu += k @ nu
        self.mu[2] = wrap(self.mu[2])
        self.sigma -= k @ s @ k.T
        self.sigma = 0.5 * (self.sigma + self.sigma.T)
        return True

    def pose_nees(self, true_pose: np.ndarray) -> float:
        """Normalised estimation error squared of the pose (3 degrees of freedom)."""
        error = self.pose - true_pose
        error[2] = wrap(error[2])
        return float(error @ np.linalg.solve(self.sigma[:3, :3], error))
