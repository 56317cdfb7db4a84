"""Localisation on a known map: EKF (covariance form) and EIF (information form), with a validation gate.

As in the 2018 thesis: the same odometry motion model and range-bearing measurements; the EIF keeps the
information matrix Omega = Sigma^-1 and vector xi = Omega mu, so its correction is additive
(Omega += H^T Q^-1 H) and its prediction needs the inversion.
"""
from __future__ import annotations

import numpy as np

from naoslam import observation
from naoslam.measurement import Measurement
from naoslam.motion import OdometryModel, VelocityModel, wrap


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
        g, v = self.motion.jacobians(self.mu, u)
        self.mu = self.motion.move(self.mu, u)
        self.sigma = g @ self.sigma @ g.T + v @ self.motion.control_noise(u) @ v.T

    def update(self, measurements: list[Measurement]) -> int:
        """Correct with every measurement of a mapped landmark that passes the gate; returns how many did."""
        used = 0
        for m in measurements:
            linear = self._linearise(self.mu, m)
            if linear is None:
                continue
            nu, h, q = linear
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
        mu = self._mu
        g, v = self.motion.jacobians(mu, u)
        self._mu = self.motion.move(mu, u)
        self.omega = np.linalg.inv(g @ np.linalg.inv(self.omega) @ g.T + v @ self.motion.control_noise(u) @ v.T)
        self.xi = self.omega @ self._mu

    def update(self, measurements: list[Measurement]) -> int:
        """Add the information of every gated measurement at once (linearised at the predicted pose)."""
        mu = self._mu
        used = 0
        for m in measurements:
            linear = self._linearise(mu, m)
            if linear is None:
                continue
            nu, h, q = linear
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
