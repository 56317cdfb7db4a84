"""Drive a SLAM back end through a time-ordered sequence of odometry and frames, and score the result."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from naoslam.ekf_slam import EkfSlam, SlamConfig
from naoslam.measurement import Measurement
from naoslam.metrics import align_se2, error_stats
from naoslam.motion import OdometryModel, VelocityModel
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
    return Sequence(events, steps[0].true_pose.copy(), OdometryModel(), walk.landmarks, f"sim {walk.config.path}")


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

    def metrics(self) -> dict:
        """``robot_error`` and ``landmark_error`` (mean, std, rmse in m), odometry error, NEES, counts."""
        out: dict = {"label": self.label, "counts": self.counts}
        if self.true_poses is not None:
            out["robot_error"] = error_stats(np.linalg.norm(self.poses[:, :2] - self.true_poses[:, :2], axis=1))
            if self.odometry_poses is not None:
                out["odometry_error"] = error_stats(np.linalg.norm(self.odometry_poses[:, :2]
                                                                   - self.true_poses[:, :2], axis=1))
        common = [k for k in self.landmarks if k in self.landmarks_truth]
        if common:
            estimated = np.array([self.landmarks[k] for k in common])
            truth = np.array([self.landmarks_truth[k] for k in common])
            if self.true_poses is None and len(common) >= 2:  # no robot truth: compare after a rigid alignment
                estimated = align_se2(estimated, truth)
            out["landmark_error"] = error_stats(np.linalg.norm(estimated - truth, axis=1))
            out["landmark_error"]["mapped"] = len(common)
            out["landmark_error"]["aligned"] = self.true_poses is None
        if self.nees is not None and len(self.nees):
            out["nees"] = {"mean": float(np.mean(self.nees)), "dof": 3}
        return out


def run_slam(sequence: Sequence, config: SlamConfig = SlamConfig(),
             pose_std: tuple[float, float, float] = (0.01, 0.01, 0.01)) -> SlamResult:
    """Run one back end over the sequence, recording the pose after every event."""
    slam = EkfSlam(sequence.start, np.diag(np.square(pose_std)), sequence.motion, config)
    times, poses, truth, odometry, nees = [], [], [], [], []
    counts = {"accepted": 0, "initialised": 0, "pending": 0, "rejected": 0}
    for event in sequence.events:
        if event.control is not None:
            slam.predict(event.control)
        if event.measurements:
            log = slam.update(event.measurements)
            for key in counts:
                counts[key] += len(getattr(log, key))
        times.append(event.t)
        poses.append(slam.pose.copy())
        if event.true_pose is not None:
            truth.append(event.true_pose)
            nees.append(slam.pose_nees(event.true_pose))
        if event.odometry_pose is not None:
            odometry.append(event.odometry_pose)
    has_truth = len(truth) == len(poses)
    return SlamResult(config.label, np.array(times), np.array(poses), np.array(truth) if has_truth else None,
                      np.array(odometry) if len(odometry) == len(poses) else None, slam.landmarks,
                      sequence.landmarks_truth, np.array(nees) if has_truth else None, counts)
