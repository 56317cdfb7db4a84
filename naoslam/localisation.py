"""Localisation on a known map: EKF (covariance form) and EIF (information form), with a validation gate.

As in the 2018 thesis: the same odometry motion model and range-bearing measurements; the EIF keeps the
information matrix Omega = Sigma^-1 and vector xi = Omega mu, so its correction is additive
(Omega += H^T Q^-1 H) and its prediction needs the inversion.

Beyond the thesis, and as in SLAM (``naoslam.ekf_slam``), by default:
- the state carries the odometry's stride and turn scales after the pose (x, y, theta, stride, turn), so a walk
  engine that misreports its stride is corrected by the landmarks instead of pulling the pose away from them with
  an over-confident covariance; ``odometry_scale_std=None`` keeps the thesis's pose-only state;
- association is by geometry with the class as evidence (``association.choose``): a detection whose class the
  front end swapped (green bands taken for blue) still corrects the pose when exactly one landmark explains it. No
  landmark takes two detections of one frame: of a second box on the same pole, only the detection nearest the
  prediction is used. Without a gate the class is the landmark (the thesis's known correspondences).
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable

import numpy as np

from naoslam import observation
from naoslam.association import Hypothesis, choose
from naoslam.measurement import Measurement
from naoslam.metrics import pose_nees
from naoslam.motion import (STRIDE_SCALE_STD, TURN_SCALE_STD, OdometryModel, VelocityModel, checked_start,
                            finite_control, scaled_step, wrap)


def checked_map(landmarks: dict[str, tuple[float, float]]) -> dict[str, np.ndarray]:
    """Where the poles stand, by class, as float (x, y) arrays; a ValueError for an empty map or a pole that is not
    two finite numbers (a localiser with nothing to correct on would follow the odometry without a word)."""
    if not landmarks:
        raise ValueError("the map holds no pole - give where at least one stands, e.g. {'bp': (1.5, -3.0)} (metres)")
    out = {}
    for name, xy in landmarks.items():
        point = np.asarray(xy, dtype=float)
        if point.shape != (2,) or not np.isfinite(point).all():
            raise ValueError(f"map pole {name!r} at {np.asarray(xy).tolist()}: give its x and y as two finite numbers "
                             "in metres")
        out[name] = point
    return out


class _Localiser(ABC):
    def __init__(self, pose: np.ndarray, pose_cov: np.ndarray, landmarks: dict[str, tuple[float, float]],
                 motion: OdometryModel | VelocityModel, gate: float | None,
                 odometry_scale_std: tuple[float, float] | None):
        observation.check_gate(gate)
        pose, pose_cov = checked_start(pose, pose_cov)
        self.map = checked_map(landmarks)
        self.motion = motion
        self.gate = gate
        self.calibrates = odometry_scale_std is not None
        self._mean = np.ones(5 if self.calibrates else 3)
        self._mean[:3] = pose
        self._prior_cov = np.zeros((len(self._mean),) * 2)
        self._prior_cov[:3, :3] = pose_cov
        if odometry_scale_std is not None:
            self._prior_cov[3, 3], self._prior_cov[4, 4] = np.square(odometry_scale_std)

    @property
    def pose(self) -> np.ndarray:
        return self._mean[:3]

    def pose_nees(self, true_pose: np.ndarray) -> float:
        """Normalised estimation error squared of the pose (3 degrees of freedom)."""
        return pose_nees(self.pose, self.covariance()[:3, :3], true_pose)

    @abstractmethod
    def covariance(self) -> np.ndarray:
        """The state's covariance."""

    @property
    def odometry_scales(self) -> tuple[float, float]:
        """Estimated (stride scale, turn scale): true motion per reported motion (1, 1 without self-calibration)."""
        return (float(self._mean[3]), float(self._mean[4])) if self.calibrates else (1.0, 1.0)

    def _step(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Move the mean with control ``u``; returns the state transition Jacobian F and the process noise."""
        u = finite_control(u)
        size = len(self._mean)
        self._mean[:3], g, g_scales, pose_noise = scaled_step(self.motion, self._mean[:3].copy(), u,
                                                              *self.odometry_scales)
        f, noise = np.eye(size), np.zeros((size, size))
        f[:3, :3], noise[:3, :3] = g, pose_noise
        if self.calibrates:
            f[:3, 3:5] = g_scales
        return f, noise

    def _linearise(self, m: Measurement, landmark: str):
        """(innovation, H over the whole state, Q) of ``m`` taken as a sighting of the mapped ``landmark``."""
        z = np.array([m.range_m, m.bearing_rad])
        nu = observation.innovation(z, observation.expected(self.pose, self.map[landmark]))
        h = np.zeros((2, len(self._mean)))
        h[:, :3] = observation.jacobians(self.pose, self.map[landmark])[0]
        return nu, h, observation.noise(m.range_std, m.bearing_std)

    def _associate(self, covariance: Callable[[], np.ndarray],
                   measurements: list[Measurement]) -> list[tuple[Measurement, str]]:
        """The frame's detections paired with the mapped landmark each one sees, in frame order, at most one a
        landmark (the nearest to the prediction). A tentative detection is paired only with a landmark of its class
        inside the gate (never without a gate). ``covariance()`` is asked for only when distances are needed."""
        if self.gate is None:
            measurements = [m for m in measurements if not m.tentative]
            pairs = [(m, m.signature) for m in measurements if m.signature in self.map]
            if len({landmark for _, landmark in pairs}) == len(pairs):
                return pairs
        sigma = covariance()

        def distance2(m: Measurement, landmark: str) -> float:
            nu, h, q = self._linearise(m, landmark)
            return float(nu @ np.linalg.solve(h @ sigma @ h.T + q, nu))

        scored = []
        for m in measurements:
            if self.gate is None:
                if m.signature in self.map:
                    scored.append((m, m.signature, distance2(m, m.signature)))
                continue
            hypotheses = [Hypothesis(name, name, distance2(m, name)) for name in self.map]
            landmark, verdict = choose(hypotheses, m.signature, self.gate)
            if m.tentative and verdict != "match":
                continue
            scored += [(m, h.landmark, h.distance2) for h in hypotheses if h.landmark == landmark]
        nearest: dict[str, tuple[Measurement, float]] = {}
        for m, landmark, d2 in scored:
            if landmark not in nearest or d2 < nearest[landmark][1]:
                nearest[landmark] = (m, d2)
        return [(m, landmark) for m, landmark, _ in scored if nearest[landmark][0] is m]


class EkfLocalisation(_Localiser):
    """EKF over the pose (and, by default, the odometry scales)."""

    def __init__(self, pose: np.ndarray, pose_cov: np.ndarray, landmarks, motion, gate=observation.CHI2_2DOF_99,
                 odometry_scale_std: tuple[float, float] | None = (STRIDE_SCALE_STD, TURN_SCALE_STD)):
        super().__init__(pose, pose_cov, landmarks, motion, gate, odometry_scale_std)
        self.sigma = self._prior_cov.copy()

    @property
    def mu(self) -> np.ndarray:
        return self._mean

    def covariance(self) -> np.ndarray:
        return self.sigma

    def predict(self, u: np.ndarray) -> None:
        f, noise = self._step(u)
        self.sigma = f @ self.sigma @ f.T + noise

    def update(self, measurements: list[Measurement]) -> int:
        """Correct with each mapped landmark's nearest detection that passes the gate; returns how many did."""
        used = 0
        for m, landmark in self._associate(self.covariance, measurements):
            nu, h, q = self._linearise(m, landmark)
            s = h @ self.sigma @ h.T + q
            s_inv = np.linalg.inv(s)
            if self.gate is not None and float(nu @ s_inv @ nu) > self.gate:
                continue
            k = self.sigma @ h.T @ s_inv
            self._mean += k @ nu
            self._mean[2] = wrap(self._mean[2])
            self.sigma = (np.eye(len(self._mean)) - k @ h) @ self.sigma
            self.sigma = 0.5 * (self.sigma + self.sigma.T)
            used += 1
        return used


class EifLocalisation(_Localiser):
    """Extended information filter over the pose (and, by default, the odometry scales)."""

    def __init__(self, pose: np.ndarray, pose_cov: np.ndarray, landmarks, motion, gate=observation.CHI2_2DOF_99,
                 odometry_scale_std: tuple[float, float] | None = (STRIDE_SCALE_STD, TURN_SCALE_STD)):
        super().__init__(pose, pose_cov, landmarks, motion, gate, odometry_scale_std)
        if np.linalg.eigvalsh(self._prior_cov).min() <= 0:
            raise ValueError("the information filter needs a start covariance with every variance above 0 (it "
                             "inverts it) - give e.g. np.diag([0.01, 0.01, 0.01]) ** 2")
        self.omega = np.linalg.inv(self._prior_cov)
        self.xi = self.omega @ self._mean

    def covariance(self) -> np.ndarray:
        return np.linalg.inv(self.omega)

    def predict(self, u: np.ndarray) -> None:
        f, noise = self._step(u)
        self.omega = np.linalg.inv(f @ np.linalg.inv(self.omega) @ f.T + noise)
        self.xi = self.omega @ self._mean

    def update(self, measurements: list[Measurement]) -> int:
        """Add the information of each mapped landmark's nearest gated detection at once (linearised at the
        predicted state)."""
        mu = self._mean.copy()
        used = 0
        for m, landmark in self._associate(self.covariance, measurements):
            nu, h, q = self._linearise(m, landmark)
            if self.gate is not None:
                s = h @ self.covariance() @ h.T + q
                if float(nu @ np.linalg.solve(s, nu)) > self.gate:
                    continue
            q_inv = np.linalg.inv(q)
            self.omega = self.omega + h.T @ q_inv @ h
            self.xi = self.xi + h.T @ q_inv @ (nu + h @ mu)
            used += 1
        if used:
            self._mean = np.linalg.solve(self.omega, self.xi)
            self._mean[2] = wrap(self._mean[2])
            self.xi = self.omega @ self._mean
        return used
