"""Drive a SLAM back end (or a localiser on a known map) through a time-ordered sequence of odometry and frames,
and score the result."""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from naoslam.ekf_slam import EkfSlam, SlamConfig
from naoslam.localisation import EifLocalisation, EkfLocalisation
from naoslam.measurement import Measurement
from naoslam.metrics import chi2_band, error_stats, fit_se2
from naoslam.motion import STRIDE_SCALE_STD, TURN_SCALE_STD, OdometryModel, VelocityModel
from naoslam.observation import CHI2_2DOF_99, check_gate
from naoslam.sim import Walk


@dataclass
class Event:
    """At time t: a control to predict with and/or the measurements of one frame, and the true pose if known."""

    t: float
    control: np.ndarray | None = None
    measurements: list[Measurement] | None = None
    true_pose: np.ndarray | None = None
    odometry_pose: np.ndarray | None = None


@dataclass
class Sequence:
    events: list[Event]
    start: np.ndarray
    motion: OdometryModel | VelocityModel
    landmarks_truth: dict[str, tuple[float, float]]
    name: str = ""


def merge_frames(controls: list[Event], frames: list[Event], time_offset_s: float = 0.0) -> list[Event]:
    """Odometry and frame events in one time order; frames shifted by ``time_offset_s`` (the thesis: +0.3 s).
    At equal times the odometry comes first."""
    shifted = [Event(f.t + time_offset_s, None, f.measurements, f.true_pose) for f in frames]
    return sorted(controls + shifted, key=lambda e: (e.t, e.measurements is not None))


def walk_sequence(walk: Walk, replace_measurements: list[list[Measurement]] | None = None) -> Sequence:
    """A simulated walk as odometry controls (rot1, trans, rot2) and frames at the same ticks."""
    events, frame = [], 0
    steps = walk.steps
    for i, step in enumerate(steps):
        control = OdometryModel.control(steps[i - 1].odometry_pose, step.odometry_pose) if i else None
        measurements = step.measurements
        if measurements is not None and replace_measurements is not None:
            measurements = replace_measurements[frame]
            frame += 1
        events.append(Event(step.t, control, measurements, step.true_pose, step.odometry_pose))
    return Sequence(events, steps[0].true_pose.copy(), OdometryModel(walk.config.odometry_alphas()), walk.landmarks,
                    walk.config.label)


@dataclass
class SlamResult:
    """Estimated path and map of one run, with the truth and odometry beside them where known."""

    label: str
    times: np.ndarray
    poses: np.ndarray
    true_poses: np.ndarray | None
    odometry_poses: np.ndarray | None
    landmarks: dict[str, np.ndarray]
    landmarks_truth: dict[str, tuple[float, float]]
    nees: np.ndarray | None
    counts: dict[str, int] = field(default_factory=dict)
    nis: np.ndarray = field(default_factory=lambda: np.zeros(0))
    time_per_step_us: dict[str, float] = field(default_factory=dict)
    odometry_scales: tuple[float, float] = (1.0, 1.0)
    #: False for a localiser: ``landmarks`` is the map it was given, not one it estimated, and is not scored.
    mapped: bool = True

    def metrics(self) -> dict:
        """Robot, odometry and landmark errors (mean, std, rmse in m), missing and phantom landmarks, NEES and NIS
        with their 95 % bands, measurement counts, time per predict and update."""
        out: dict = {"label": self.label, "counts": self.counts, "time_per_step_us": self.time_per_step_us,
                     "odometry_scales": {"stride": self.odometry_scales[0], "turn": self.odometry_scales[1]}}
        if self.true_poses is not None:
            out["robot_error"] = error_stats(np.linalg.norm(self.poses[:, :2] - self.true_poses[:, :2], axis=1))
            if self.odometry_poses is not None:
                out["odometry_error"] = error_stats(np.linalg.norm(self.odometry_poses[:, :2]
                                                                   - self.true_poses[:, :2], axis=1))
        if self.landmarks_truth and self.mapped:
            out.update(score_map(self.landmarks, self.landmarks_truth, align=self.true_poses is None))
        if self.nees is not None and len(self.nees):
            band = chi2_band(3)
            out["nees"] = {"mean": float(np.mean(self.nees)), "median": float(np.median(self.nees)), "dof": 3,
                           "band95": band, "inside_band": float(np.mean((self.nees >= band[0])
                                                                        & (self.nees <= band[1])))}
        if len(self.nis):
            band = chi2_band(2)
            out["nis"] = {"mean": float(np.mean(self.nis)), "dof": 2, "band95": band,
                          "inside_band": float(np.mean((self.nis >= band[0]) & (self.nis <= band[1])))}
        return out

    def truth_alignment(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The rotation and translation that scoring applies to the map of a run without robot truth (a log whose
        start is its own origin), to draw path and map in the truth's frame; None where scoring aligns nothing."""
        if self.true_poses is not None or not self.mapped:
            return None
        return fit_to_truth(self.landmarks, self.landmarks_truth)


def match_to_truth(landmarks: dict[str, np.ndarray], truth: dict[str, tuple[float, float]]) -> dict[str, str]:
    """Each true landmark's nearest mapped landmark of its class (names ``yp``, ``yp#2``: class ``yp``), by name."""
    by_class: dict[str, list[str]] = {}
    for name in landmarks:
        by_class.setdefault(name.split("#")[0], []).append(name)
    matched: dict[str, str] = {}
    for label, position in truth.items():
        names = by_class.get(label, [])
        if names:
            matched[label] = min(names, key=lambda n: float(np.linalg.norm(landmarks[n] - position)))
    return matched


def fit_to_truth(landmarks: dict[str, np.ndarray],
                 truth: dict[str, tuple[float, float]]) -> tuple[np.ndarray, np.ndarray] | None:
    """The rotation and translation that best fit the mapped landmarks matched to the truth onto it; None with
    fewer than two matches."""
    matched = match_to_truth(landmarks, truth)
    if len(matched) < 2:
        return None
    return fit_se2(np.array([landmarks[matched[k]] for k in matched]), np.array([truth[k] for k in matched]))


def score_map(landmarks: dict[str, np.ndarray], truth: dict[str, tuple[float, float]], align: bool) -> dict:
    """Each true landmark against the nearest mapped landmark of its class (names ``yp``, ``yp#2``: class ``yp``).

    Unmatched true landmarks are ``missing``; every other mapped landmark is a ``phantom``, reported with its
    distance to the nearest true landmark. Without robot truth (``align``) the matched map is first moved by the
    rigid transform that fits it best.
    """
    matched = match_to_truth(landmarks, truth)
    out: dict = {"landmarks_missing": sorted(set(truth) - set(matched))}
    if matched:
        estimated = np.array([landmarks[matched[k]] for k in matched])
        reference = np.array([truth[k] for k in matched])
        fit = fit_to_truth(landmarks, truth) if align else None
        if fit is not None:
            rotation, translation = fit
            estimated = estimated @ rotation.T + translation
        out["landmark_error"] = {**error_stats(np.linalg.norm(estimated - reference, axis=1)),
                                 "mapped": len(matched), "of": len(truth), "aligned": align}
    points = np.array(list(truth.values()), dtype=float)
    out["phantoms"] = {name: float(np.min(np.linalg.norm(points - position, axis=1)))
                       for name, position in landmarks.items() if name not in matched.values()}
    return out


@dataclass(frozen=True)
class LocalisationConfig:
    """Localisation on a known map as a back end beside SLAM: the EKF or the EIF (``information_form``), with the
    odometry scales in the state or without them (the 2018 thesis's pose-only filter), with a validation gate or
    none. ``landmarks`` is the map (class -> (x, y)); None takes the sequence's true map."""

    information_form: bool = False
    self_calibrate: bool = True
    gate: float | None = CHI2_2DOF_99
    landmarks: dict[str, tuple[float, float]] | None = None

    def __post_init__(self) -> None:
        check_gate(self.gate)

    @property
    def label(self) -> str:
        form = "EIF" if self.information_form else "EKF"
        source = "the known map" if self.landmarks is None else "a given map"
        return f"{form} localisation on {source}" + ("" if self.self_calibrate else ", no odometry scales")

    def build(self, sequence: Sequence, pose_cov: np.ndarray) -> EkfLocalisation | EifLocalisation:
        """The localiser at the sequence's start on its map."""
        localiser = EifLocalisation if self.information_form else EkfLocalisation
        scales = (STRIDE_SCALE_STD, TURN_SCALE_STD) if self.self_calibrate else None
        landmarks = sequence.landmarks_truth if self.landmarks is None else self.landmarks
        return localiser(sequence.start, pose_cov, landmarks, sequence.motion, self.gate, odometry_scale_std=scales)


def localisable(sequence: Sequence) -> bool:
    """Whether localisation can run on the sequence: its true map is known and its start is a true pose in that map
    (a simulated walk; not a UTIAS log without robot truth, nor a recording)."""
    first = sequence.events[0].true_pose if sequence.events else None
    return bool(sequence.landmarks_truth) and first is not None and np.allclose(first, sequence.start)


def run_slam(sequence: Sequence, config: SlamConfig | LocalisationConfig = SlamConfig(),
             pose_std: tuple[float, float, float] = (0.01, 0.01, 0.01)) -> SlamResult:
    """Run one back end over the sequence, recording the pose after every event and the time each step took.
    Every frame is folded in, one without detections too, as a robot's loop does (it ages the pending candidates).
    A localiser (``LocalisationConfig``) counts its used detections as accepted and maps nothing of its own."""
    pose_cov = np.diag(np.square(pose_std))
    localising = isinstance(config, LocalisationConfig)
    slam = config.build(sequence, pose_cov) if localising else EkfSlam(sequence.start, pose_cov, sequence.motion,
                                                                        config)
    times, poses, truth, odometry, nees, nis = [], [], [], [], [], []
    predict_ns, update_ns = [], []
    counts = {"accepted": 0, "confused": 0, "initialised": 0, "pending": 0, "rejected": 0, "unconfirmed": 0}
    for event in sequence.events:
        if event.control is not None:
            start = time.perf_counter_ns()
            slam.predict(event.control)
            predict_ns.append(time.perf_counter_ns() - start)
        if event.measurements is not None:
            start = time.perf_counter_ns()
            log = slam.update(event.measurements)
            update_ns.append(time.perf_counter_ns() - start)
            if localising:
                counts["accepted"] += log
            else:
                for key in counts:
                    counts[key] += len(getattr(log, key))
                nis += log.nis
        times.append(event.t)
        poses.append(slam.pose.copy())
        if event.true_pose is not None:
            truth.append(event.true_pose)
            nees.append(slam.pose_nees(event.true_pose))
        if event.odometry_pose is not None:
            odometry.append(event.odometry_pose)
    has_truth = len(truth) == len(poses)
    timing = {"predict": float(np.mean(predict_ns)) / 1e3 if predict_ns else 0.0,
              "update": float(np.mean(update_ns)) / 1e3 if update_ns else 0.0}
    return SlamResult(config.label, np.array(times), np.array(poses), np.array(truth) if has_truth else None,
                      np.array(odometry) if len(odometry) == len(poses) else None,
                      slam.map if localising else slam.landmarks, sequence.landmarks_truth,
                      np.array(nees) if has_truth else None, counts, np.array(nis), timing, slam.odometry_scales,
                      mapped=not localising)
