"""Localisation on a known map: EKF (covariance form) and EIF (information form), with a validation gate.

As in the 2018 thesis: the same odometry motion model and range-bearing measurements; the EIF keeps the
information matrix Omega = Sigma^-1 and vector xi = Omega mu, so its correction is additive
(Omega += H^T Q^-1 H) and its prediction needs the inversion. As in SLAM, no landmark takes two detections of one
frame: of a second box on the same pole, only the detection nearest the prediction is used.
"""
from __future__ import annotations

from collections import Counter
from collections.abc import Callable

import numpy as np

from naoslam import observation
from naoslam.measurement import Measurement
from naoslam.motion import OdometryModel, VelocityModel, finite_control, wrap


class _Localiser:
    def __init__(self, landmarks: dict[str, tuple[float, float]], motion: OdometryModel | VelocityModel,
                 gate: float | None = observation.CHI2_2DOF_99):
        self.map = {k: np.asarray(v, dtype=float) for k, v in landmarks.items()}
        self.motion = motion
        self.gate = gate

    def _linearise(self, pose: np.ndarray, m: Measurement):
        landmark = self.map.get(m.signature)
        if landmark is None:
            return None
        z = np.array([m.range_m, m.bearing_rad])
        nu = observation.innovation(z, observation.expected(pose, landmark))
        h = observation.jacobians(pose, landmark)[0]
        return nu, h, observation.noise(m.range_std, m.bearing_std)

    def _one_per_landmark(self, pose: np.ndarray, covariance: Callable[[], np.ndarray],
                          measurements: list[Measurement]) -> list[Measurement]:
        """The frame's detections of mapped landmarks, in order, keeping of a landmark detected twice only the
        detection nearest the prediction (Mahalanobis distance at ``pose`` and ``covariance()``, asked for only then).
        """
        counts = Counter(m.signature for m in measurements)
        repeated = [name for name, n in counts.items() if n > 1 and name in self.map]
        mapped = [m for m in measurements if m.signature in self.map]
        if not repeated:
            return mapped
        sigma = covariance()

        def distance2(m: Measurement) -> float:
            nu, h, q = self._linearise(pose, m)
            return float(nu @ np.linalg.solve(h @ sigma @ h.T + q, nu))

        nearest = {name: min((m for m in mapped if m.signature == name), key=distance2) for name in repeated}
        return [m for m in mapped if nearest.get(m.signature, m) is m]


class EkfLocalisation(_Localiser):
    """Pose-only EKF."""

    def __init__(self, pose: np.ndarray, pose_cov: np.ndarray, landmarks, motion, gate=observation.CHI2_2DOF_99):
        super().__init__(landmarks, motion, gate)
        self.mu = np.asarray(pose, dtype=float).copy()
        self.sigma = np.asarray(pose_cov, dtype=float).copy()

    @property
    def pose(self) -> np.ndarray:
        return self.mu

    def predict(self, u: np.ndarray) -> None:
        u = finite_control(u)
        g, v = self.motion.jacobians(self.mu, u)
        self.mu = self.motion.move(self.mu, u)
        self.sigma = g @ self.sigma @ g.T + v @ self.motion.control_noise(u) @ v.T

    def update(self, measurements: list[Measurement]) -> int:
        """Correct with each mapped landmark's nearest detection that passes the gate; returns how many did."""
        used = 0
        for m in self._one_per_landmark(self.mu, lambda: self.sigma, measurements):
            nu, h, q = self._linearise(self.mu, m)
            s = h @ self.sigma @ h.T + q
            s_inv = np.linalg.inv(s)
            if self.gate is not None and float(nu @ s_inv @ nu) > self.gate:
                continue
            k = self.sigma @ h.T @ s_inv
            self.mu = self.mu + k @ nu
            self.mu[2] = wrap(self.mu[2])
            self.sigma = (np.eye(3) - k @ h) @ self.sigma
            self.sigma = 0.5 * (self.sigma + self.sigma.T)
            used += 1
        return used


class EifLocalisation(_Localiser):
    """Pose-only extended information filter."""

    def __init__(self, pose: np.ndarray, pose_cov: np.ndarray, landmarks, motion, gate=observation.CHI2_2DOF_99):
        super().__init__(landmarks, motion, gate)
        self.omega = np.linalg.inv(np.asarray(pose_cov, dtype=float))
        self.xi = self.omega @ np.asarray(pose, dtype=float)
        self._mu = np.asarray(pose, dtype=float).copy()

    @property
    def pose(self) -> np.ndarray:
        return self._mu

    def predict(self, u: np.ndarray) -> None:
        u = finite_control(u)
        mu = self._mu
        g, v = self.motion.jacobians(mu, u)
        self._mu = self.motion.move(mu, u)
        self.omega = np.linalg.inv(g @ np.linalg.inv(self.omega) @ g.T + v @ self.motion.control_noise(u) @ v.T)
        self.xi = self.omega @ self._mu

    def update(self, measurements: list[Measurement]) -> int:
        """Add the information of each mapped landmark's nearest gated detection at once (linearised at the
        predicted pose)."""
        mu = self._mu
        used = 0
        for m in self._one_per_landmark(mu, lambda: np.linalg.inv(self.omega), measurements):
            nu, h, q = self._linearise(mu, m)
            if self.gate is not None:
                s = h @ np.linalg.inv(self.omega) @ h.T + q
                if float(nu @ np.linalg.solve(s, nu)) > self.gate:
                    continue
            q_inv = np.linalg.inv(q)
            self.omega = self.omega + h.T @ q_inv @ h
            self.xi = self.xi + h.T @ q_inv @ (nu + h @ mu)
            used += 1
        if used:
            self._mu = np.linalg.solve(self.omega, self.xi)
            self._mu[2] = wrap(self._mu[2])
            self.xi = self.omega @ self._mu
        return used
