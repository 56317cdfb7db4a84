"""Motion models for a planar robot pose (x, y, theta): odometry (rot1, trans, rot2) and velocity (v, w, dt).

Each model gives the new pose, its Jacobian G with respect to the pose, V with respect to the control, and the
control noise M (Thrun, Burgard and Fox, Probabilistic Robotics, 5.3-5.4), so the pose noise is V M V^T.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


def wrap(angle: float | np.ndarray) -> float | np.ndarray:
    """Angle wrapped to (-pi, pi]."""
    return np.arctan2(np.sin(angle), np.cos(angle))


def finite_control(u: np.ndarray) -> np.ndarray:
    """``u`` as three floats, or a ValueError before any filter state changes: one NaN from an odometry glitch would
    otherwise turn the pose and every covariance into NaN for good. With odometry controls, skip the step and build
    the next control from the last good odometry pose: no motion is lost."""
    control = np.asarray(u, dtype=float)
    if control.shape != (3,) or not np.isfinite(control).all():
        raise ValueError(f"control {np.asarray(u).tolist()} is not three finite numbers - the filter was not moved; "
                         "skip this odometry step")
    return control


def checked_start(pose: np.ndarray, pose_cov: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The start pose (x, y, theta) and its 3x3 covariance as floats, or a ValueError that says what is wrong: a NaN
    would spread to every estimate, and a covariance that is not symmetric with no negative variance makes every
    uncertainty the filter reports meaningless."""
    mean, cov = np.asarray(pose, dtype=float), np.asarray(pose_cov, dtype=float)
    if mean.shape != (3,) or not np.isfinite(mean).all():
        raise ValueError(f"start pose {np.asarray(pose).tolist()} is not three finite numbers (x m, y m, theta rad)")
    if (cov.shape != (3, 3) or not np.isfinite(cov).all() or not np.allclose(cov, cov.T)
            or np.linalg.eigvalsh(cov).min() < -1e-12 * max(1.0, float(np.trace(cov)))):
        raise ValueError(f"start covariance of shape {cov.shape} is not a symmetric 3x3 matrix with no negative "
                         "variance - give e.g. np.diag([0.01, 0.01, 0.01]) ** 2 (x m, y m, theta rad)")
    return mean, cov


def check_alphas(alphas: tuple[float, float, float, float]) -> None:
    """A ValueError unless the control-noise coefficients are four finite numbers, none negative."""
    values = np.asarray(alphas, dtype=float)
    if values.shape != (4,) or not np.isfinite(values).all() or (values < 0).any():
        raise ValueError(f"noise alphas {list(alphas)} must be four finite numbers, none negative (variance "
                         "coefficients, e.g. (0.1, 0.02, 0.1, 0.02))")


#: Prior standard deviations of the odometry scales (true motion per reported motion, mean 1) that SLAM and
#: localisation estimate: a Nao's walk engine misreports its stride by tens of percent, its turns by less.
STRIDE_SCALE_STD = 0.3
TURN_SCALE_STD = 0.1


def scaled_step(motion: OdometryModel | VelocityModel, pose: np.ndarray, u: np.ndarray, stride: float, turn: float
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One prediction of a pose under reported control ``u`` with odometry scales ``stride`` and ``turn``.

    Returns the new pose, G = d pose' / d pose (3x3), d pose' / d (stride, turn) (3x2) and the pose noise V M V^T of
    the true (scaled) control: what a filter with the scales in its state needs to propagate its robot block.
    """
    true_u = motion.scaled(u, stride, turn)
    g, v = motion.jacobians(pose, true_u)
    d_stride, d_turn = motion.scale_directions(u)
    return (motion.move(pose, true_u), g, np.column_stack([v @ d_stride, v @ d_turn]),
            v @ motion.control_noise(true_u) @ v.T)


@dataclass(frozen=True)
class OdometryModel:
    """Odometry as rot1, trans, rot2 between two odometry poses; alphas scale the control noise."""

    alphas: tuple[float, float, float, float] = (0.1, 0.02, 0.1, 0.02)

    def __post_init__(self) -> None:
        check_alphas(self.alphas)

    @staticmethod
    def control(previous: np.ndarray, current: np.ndarray) -> np.ndarray:
        """(rot1, trans, rot2) that takes odometry pose ``previous`` to ``current``."""
        dx, dy = current[0] - previous[0], current[1] - previous[1]
        trans = math.hypot(dx, dy)
        rot1 = float(wrap(math.atan2(dy, dx) - previous[2])) if trans > 1e-9 else 0.0
        rot2 = float(wrap(current[2] - previous[2] - rot1))
        return np.array([rot1, trans, rot2])

    @staticmethod
    def scaled(u: np.ndarray, stride: float, turn: float) -> np.ndarray:
        """The true motion of reported control ``u``: translation times ``stride``, rotations times ``turn``."""
        return np.array([u[0] * turn, u[1] * stride, u[2] * turn])

    @staticmethod
    def scale_directions(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """d scaled(u) / d stride and d scaled(u) / d turn, in the control space of V."""
        return np.array([0.0, u[1], 0.0]), np.array([u[0], 0.0, u[2]])

    @staticmethod
    def move(pose: np.ndarray, u: np.ndarray) -> np.ndarray:
        rot1, trans, rot2 = u
        heading = pose[2] + rot1
        return np.array([pose[0] + trans * math.cos(heading), pose[1] + trans * math.sin(heading),
                         float(wrap(heading + rot2))])

    @staticmethod
    def jacobians(pose: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """G = d move / d pose and V = d move / d control."""
        rot1, trans, _ = u
        heading = pose[2] + rot1
        s, c = math.sin(heading), math.cos(heading)
        g = np.array([[1.0, 0.0, -trans * s], [0.0, 1.0, trans * c], [0.0, 0.0, 1.0]])
        v = np.array([[-trans * s, c, 0.0], [trans * c, s, 0.0], [1.0, 0.0, 1.0]])
        return g, v

    def control_noise(self, u: np.ndarray) -> np.ndarray:
        a1, a2, a3, a4 = self.alphas
        rot1, trans, rot2 = np.abs(u)
        return np.diag([a1 * rot1 ** 2 + a2 * trans ** 2 + 1e-8,
                        a3 * trans ** 2 + a4 * (rot1 ** 2 + rot2 ** 2) + 1e-8,
                        a1 * rot2 ** 2 + a2 * trans ** 2 + 1e-8])


@dataclass(frozen=True)
class VelocityModel:
    """Velocity control (v, w) held for dt seconds along a circular arc; alphas scale the control noise.

    The noise is a rate (per second), so the pose uncertainty grows with time and not with the odometry rate.
    """

    alphas: tuple[float, float, float, float] = (0.1, 0.01, 0.01, 0.1)

    def __post_init__(self) -> None:
        check_alphas(self.alphas)

    @staticmethod
    def scaled(u: np.ndarray, stride: float, turn: float) -> np.ndarray:
        """The true motion of reported control ``u``: speed times ``stride``, turn rate times ``turn``."""
        return np.array([u[0] * stride, u[1] * turn, u[2]])

    @staticmethod
    def scale_directions(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """d scaled(u) / d stride and d scaled(u) / d turn, in the control space of V (v, w)."""
        return np.array([u[0], 0.0]), np.array([0.0, u[1]])

    @staticmethod
    def move(pose: np.ndarray, u: np.ndarray) -> np.ndarray:
        v, w, dt = u
        theta = pose[2]
        if abs(w) < 1e-9:
            return np.array([pose[0] + v * dt * math.cos(theta), pose[1] + v * dt * math.sin(theta), theta])
        r = v / w
        return np.array([pose[0] - r * math.sin(theta) + r * math.sin(theta + w * dt),
                         pose[1] + r * math.cos(theta) - r * math.cos(theta + w * dt),
                         float(wrap(theta + w * dt))])

    @staticmethod
    def jacobians(pose: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """G = d move / d pose and V = d move / d (v, w)."""
        v, w, dt = u
        theta = pose[2]
        s, c = math.sin(theta), math.cos(theta)
        if abs(w) < 1e-9:
            g = np.array([[1.0, 0.0, -v * dt * s], [0.0, 1.0, v * dt * c], [0.0, 0.0, 1.0]])
            vj = np.array([[dt * c, -0.5 * v * dt ** 2 * s], [dt * s, 0.5 * v * dt ** 2 * c], [0.0, dt]])
            return g, vj
        s2, c2 = math.sin(theta + w * dt), math.cos(theta + w * dt)
        g = np.array([[1.0, 0.0, v / w * (-c + c2)], [0.0, 1.0, v / w * (-s + s2)], [0.0, 0.0, 1.0]])
        vj = np.array([[(-s + s2) / w, v * (s - s2) / w ** 2 + v * c2 * dt / w],
                       [(c - c2) / w, -v * (c - c2) / w ** 2 + v * s2 * dt / w],
                       [0.0, dt]])
        return g, vj

    def control_noise(self, u: np.ndarray) -> np.ndarray:
        a1, a2, a3, a4 = self.alphas
        v, w, dt = np.abs(u)
        per_second = 1.0 / max(dt, 1e-3)
        return np.diag([a1 * v ** 2 + a2 * w ** 2 + 1e-8, a3 * v ** 2 + a4 * w ** 2 + 1e-8]) * per_second
