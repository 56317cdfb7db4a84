"""EKF SLAM over a robot block and a growing map of point landmarks, with the variants the thesis compared.

State: the robot block - pose (x, y, theta), then, with odometry self-calibration, the stride scale and turn scale
that turn reported odometry into true motion - followed by (x, y) of each landmark in the order they entered the
map. Updates touch only the robot block and the observed landmark through index slices: O(n) for the gain and
O(n^2) for the covariance (Joseph form).

Defaults are the robust configuration: self-calibrated odometry, class-tolerant nearest-neighbour association
inside a Mahalanobis gate, and landmarks initialised only from three agreeing sightings, never within half a metre
of a mapped one. The thesis's variants (2024 thesis, 3.2) stay available for the comparison tables through
:meth:`SlamConfig.thesis`:
- outlier filter: drop a measurement whose range differs more than 0.4 m or bearing more than pi/3 from prediction;
- minimal view: a landmark enters the map only after ``min_views`` sightings that agree in position;
- FEJ-EKF (Huang, Mourikis and Roumeliotis 2009): the motion Jacobian uses the displacement between *predicted*
  poses, and the measurement Jacobian the landmark's first estimate;
- OC-EKF (Huang, Mourikis and Roumeliotis 2010): the motion Jacobian as FEJ, and the measurement Jacobian
  projected so that it cannot see a global translation or rotation (the directions SLAM cannot observe).
"""
from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from naoslam import observation
from naoslam.association import CandidatePool, Hypothesis, choose
from naoslam.measurement import Measurement
from naoslam.metrics import pose_nees
from naoslam.motion import (STRIDE_SCALE_STD, TURN_SCALE_STD, OdometryModel, VelocityModel, checked_start,
                             finite_control, scaled_step, wrap)

OUTLIER_RANGE_M = 0.4
OUTLIER_BEARING_RAD = math.pi / 3
ASSOCIATIONS = ("nearest", "class")
LINEARISATIONS = ("standard", "fej", "oc")


@dataclass(frozen=True)
class SlamConfig:
    """Which back end to run; the defaults are the robust one.

    ``linearisation``: standard, fej or oc. ``gate``: chi-square bound (2 dof) on every update, or None.
    ``association``: ``nearest`` (geometry, class as evidence) or ``class`` (the class is the landmark's identity:
    known correspondences, the thesis's mode). ``min_views``: agreeing sightings before a landmark enters the map.
    ``min_separation_m`` (nearest-neighbour association): no landmark enters the map this close to a mapped one;
    two poles never stand that close, so such a sighting is that pole again (a second box, a biased range). 0: off.
    ``self_calibrate``: estimate stride and turn scale with priors (mean 1, standard deviations below).
    """

    linearisation: str = "oc"
    outlier_filter: bool = False
    gate: float | None = observation.CHI2_2DOF_99
    min_views: int = 3
    min_separation_m: float = 0.5
    association: str = "nearest"
    self_calibrate: bool = True
    stride_scale_std: float = STRIDE_SCALE_STD
    turn_scale_std: float = TURN_SCALE_STD

    def __post_init__(self) -> None:
        if self.min_views < 1:
            raise ValueError(f"min_views {self.min_views} must be at least 1")
        if not 0 <= self.min_separation_m < math.inf:
            raise ValueError(f"min_separation_m {self.min_separation_m} must be a distance in metres, 0 or more")
        observation.check_gate(self.gate)
        if self.linearisation not in LINEARISATIONS:
            raise ValueError(f"linearisation {self.linearisation!r} is not one of {', '.join(LINEARISATIONS)}")
        if self.association not in ASSOCIATIONS:
            raise ValueError(f"association {self.association!r} is not one of {', '.join(ASSOCIATIONS)}")

    @classmethod
    def thesis(cls, **variant) -> "SlamConfig":
        """The thesis's classic EKF (known correspondences, no gate, immediate initialisation, raw odometry) with
        ``variant`` switched on."""
        return cls(**{"linearisation": "standard", "gate": None, "min_views": 1, "association": "class",
                      "self_calibrate": False, **variant})

    @property
    def label(self) -> str:
        parts = [{"standard": "EKF", "fej": "FEJ-EKF", "oc": "OC-EKF"}[self.linearisation]]
        if self.self_calibrate:
            parts.append("odometry scales")
        if self.association == "nearest":
            parts.append("NN association")
            if self.min_separation_m:
                parts.append(f"separation {self.min_separation_m:g} m")
        if self.outlier_filter:
            parts.append("outlier filter")
        if self.gate:
            parts.append(f"gate {self.gate:g}")
        if self.min_views > 1:
            parts.append(f"min view {self.min_views}")
        return " + ".join(parts)


@dataclass
class UpdateLog:
    """What happened to each measurement of one update (by detected class), and the accepted updates' NIS."""

    accepted: list[str] = field(default_factory=list)
    confused: list[str] = field(default_factory=list)
    initialised: list[str] = field(default_factory=list)
    pending: list[str] = field(default_factory=list)
    rejected: list[str] = field(default_factory=list)
    #: Tentative sightings that confirmed no mapped landmark of their class, and were dropped.
    unconfirmed: list[str] = field(default_factory=list)
    nis: list[float] = field(default_factory=list)


class EkfSlam:
    """EKF SLAM over a pose (plus odometry scales) and a growing map of point landmarks."""

    def __init__(self, pose: np.ndarray, pose_cov: np.ndarray, motion: OdometryModel | VelocityModel,
                 config: SlamConfig = SlamConfig()):
        pose, pose_cov = checked_start(pose, pose_cov)
        self.config = config
        self.motion = motion
        self.robot_size = 5 if config.self_calibrate else 3
        self.mu = np.zeros(self.robot_size)
        self.mu[:3] = pose
        self.sigma = np.zeros((self.robot_size, self.robot_size))
        self.sigma[:3, :3] = pose_cov
        if config.self_calibrate:
            self.mu[3:5] = 1.0
            self.sigma[3, 3], self.sigma[4, 4] = config.stride_scale_std ** 2, config.turn_scale_std ** 2
        self.slots: dict[str, int] = {}
        self.votes: dict[str, Counter] = {}
        self.first_estimates: dict[str, np.ndarray] = {}
        self.pools: dict[str, CandidatePool] = {}
        self.frame = 0
        self._previous_predicted = self.mu[:3].copy()

    @property
    def pose(self) -> np.ndarray:
        return self.mu[:3]

    @property
    def odometry_scales(self) -> tuple[float, float]:
        """Estimated (stride scale, turn scale): true motion per reported motion (1, 1 without self-calibration)."""
        return (float(self.mu[3]), float(self.mu[4])) if self.config.self_calibrate else (1.0, 1.0)

    def label_of(self, landmark: str) -> str:
        """The class most often detected on a landmark."""
        return self.votes[landmark].most_common(1)[0][0]

    @property
    def landmarks(self) -> dict[str, np.ndarray]:
        """Estimated landmark positions by name: the majority class, ``#2``, ``#3`` for later ones of that class."""
        out: dict[str, np.ndarray] = {}
        for landmark, i in self.slots.items():
            label = name = self.label_of(landmark)
            n = 1
            while name in out:
                n += 1
                name = f"{label}#{n}"
            out[name] = self.mu[i:i + 2].copy()
        return out

    def predict(self, u: np.ndarray) -> None:
        """Move the pose with reported control ``u`` (scaled by the estimated odometry scales); a control that is not
        finite is refused (``finite_control``) and the filter is left as it was."""
        u = finite_control(u)
        r = self.robot_size
        self.mu[:3], g, g_scales, pose_noise = scaled_step(self.motion, self.mu[:3].copy(), u, *self.odometry_scales)
        if self.config.linearisation != "standard":
            # Huang et al.: linearise at the previous *predicted* pose, not the updated one.
            dx, dy = self.mu[:2] - self._previous_predicted[:2]
            g = np.array([[1.0, 0.0, -dy], [0.0, 1.0, dx], [0.0, 0.0, 1.0]])
        self._previous_predicted = self.mu[:3].copy()
        f = np.eye(r)
        f[:3, :3] = g
        if self.config.self_calibrate:
            f[:3, 3:5] = g_scales
        sigma = self.sigma
        sigma[:r, :r] = f @ sigma[:r, :r] @ f.T
        sigma[:3, :3] += pose_noise
        sigma[:r, r:] = f @ sigma[:r, r:]
        sigma[r:, :r] = sigma[:r, r:].T

    def update(self, measurements: list[Measurement]) -> UpdateLog:
        """Fold in one frame's measurements, one at a time; no landmark takes two detections of one frame. A
        tentative measurement is taken only where it matches a mapped landmark of its class inside the gate."""
        self.frame += 1
        log = UpdateLog()
        used: set[str] = set()
        for m in measurements:
            z = np.array([m.range_m, m.bearing_rad])
            q = observation.noise(m.range_std, m.bearing_std)
            landmark, verdict, linearised = self._associate(m.signature, z, q, used)
            if m.tentative and verdict != "match":
                log.unconfirmed.append(m.signature)
                continue
            if landmark is not None:
                nis = self._correct(linearised)
                if nis is None:
                    log.rejected.append(m.signature)
                    continue
                used.add(landmark)
                self.votes[landmark][m.signature] += 1
                (log.confused if verdict == "confused" else log.accepted).append(m.signature)
                log.nis.append(nis)
            elif verdict == "ambiguous":
                log.rejected.append(m.signature)
            else:
                label = self._seen_enough(m.signature, z, q)
                if label is None:
                    log.pending.append(m.signature)
                else:
                    used.add(self._add_landmark(label, z, q))
                    log.initialised.append(m.signature)
        return log

    def _associate(self, detected: str, z: np.ndarray, q: np.ndarray, used: set[str]):
        """(landmark, verdict, its linearisation) for one detection; landmark and linearisation None when none fits."""
        if self.config.association == "class":
            if detected not in self.slots:
                return None, "new", None
            if detected in used:  # a second detection of that landmark in this frame: not a new landmark
                return None, "ambiguous", None
            return detected, "match", self._linearise(detected, z, q)
        linearised, hypotheses = {}, []
        for landmark in self.slots:
            if landmark not in used:
                linearised[landmark] = nu, s, *_ = self._linearise(landmark, z, q)
                hypotheses.append(Hypothesis(landmark, self.label_of(landmark), float(nu @ np.linalg.solve(s, nu))))
        landmark, verdict = choose(hypotheses, detected, self.config.gate or observation.CHI2_2DOF_99)
        if verdict == "new" and self._crowds_the_map(z):
            verdict = "ambiguous"
        return landmark, verdict, linearised.get(landmark)

    def _crowds_the_map(self, z: np.ndarray) -> bool:
        """True when a sighting puts its pole within ``min_separation_m`` of a mapped landmark, taken in this frame
        or not: that landmark seen again, never a new one."""
        if not self.config.min_separation_m or not self.slots:
            return False
        position = observation.landmark_from(self.pose, z)[0]
        return any(math.dist(self.mu[i:i + 2], position) < self.config.min_separation_m for i in self.slots.values())

    def _seen_enough(self, detected: str, z: np.ndarray, q: np.ndarray) -> str | None:
        """Delayed initialisation: the class to map when this sighting completes a candidate, else None."""
        if self.config.min_views == 1:
            return detected
        position, _, j_z = observation.landmark_from(self.pose, z)
        key = detected if self.config.association == "class" else ""
        pool = self.pools.setdefault(key, CandidatePool(self.config.min_views))
        return pool.sighting(position, j_z @ q @ j_z.T, detected, self.frame)

    def _add_landmark(self, label: str, z: np.ndarray, q: np.ndarray) -> str:
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
        landmark = label if self.config.association == "class" else f"L{len(self.slots)}"
        self.slots[landmark] = n
        self.votes[landmark] = Counter({label: 1})
        self.first_estimates[landmark] = position.copy()
        return landmark

    def _linearise(self, landmark: str, z: np.ndarray, q: np.ndarray):
        """Innovation, its covariance S, the Jacobian H over (pose, landmark), those state indices, and Q."""
        j = self.slots[landmark]
        estimate = self.mu[j:j + 2]
        nu = observation.innovation(z, observation.expected(self.pose, estimate))
        at = self.first_estimates[landmark] if self.config.linearisation == "fej" else estimate
        h = np.hstack(observation.jacobians(self.pose, at))
        if self.config.linearisation == "oc":
            h = _observable_part(h, self._previous_predicted, self.first_estimates[landmark])
        idx = np.r_[0:3, j:j + 2]
        s = h @ self.sigma[np.ix_(idx, idx)] @ h.T + q
        return nu, s, h, idx, q

    def _correct(self, linearised) -> float | None:
        """Joseph-form update from a landmark's linearisation (:meth:`_linearise`); the NIS when accepted, None when
        the outlier filter or the gate rejects it."""
        nu, s, h, idx, q = linearised
        if self.config.outlier_filter and (abs(nu[0]) > OUTLIER_RANGE_M or abs(nu[1]) > OUTLIER_BEARING_RAD):
            return None
        nis = float(nu @ np.linalg.solve(s, nu))
        if self.config.gate is not None and nis > self.config.gate:
            return None
        p = self.sigma[:, idx] @ h.T  # Sigma H^T, n x 2
        k = np.linalg.solve(s, p.T).T
        self.mu += k @ nu
        self.mu[2] = wrap(self.mu[2])
        # Joseph form (I - KH) Sigma (I - KH)^T + K Q K^T, expanded so that only Sigma H^T is needed: stays
        # symmetric positive semi-definite under rounding, unlike Sigma - K S K^T.
        kp = k @ p.T
        self.sigma += k @ s @ k.T - kp - kp.T
        self.sigma = 0.5 * (self.sigma + self.sigma.T)
        return nis

    def pose_nees(self, true_pose: np.ndarray) -> float:
        """Normalised estimation error squared of the pose (3 degrees of freedom)."""
        return pose_nees(self.pose, self.sigma[:3, :3], true_pose)


def _observable_part(h: np.ndarray, pose: np.ndarray, landmark: np.ndarray) -> np.ndarray:
    """OC-EKF: the measurement Jacobian over (pose, landmark) nearest to ``h`` (Frobenius norm) that is blind to
    the unobservable directions - a common translation in x and y, and a rotation about the origin.

    The directions are the ones the motion Jacobians have carried forward: the rotation's robot part at the
    *predicted* position, its landmark part at the landmark's first estimate (Huang, Mourikis and Roumeliotis
    2010). At the current estimates the projection would change nothing: the standard Jacobian is already blind
    to the rotation about its own linearisation point; it is the mismatch over time that gains false information.
    """
    u = np.array([[1.0, 0.0, -pose[1]], [0.0, 1.0, pose[0]], [0.0, 0.0, 1.0],
                  [1.0, 0.0, -landmark[1]], [0.0, 1.0, landmark[0]]])
    return h - h @ u @ np.linalg.solve(u.T @ u, u.T)
