"""The accuracy reference for the online filters: a batch smoother (GTSAM, Levenberg-Marquardt) on the same walk.

It solves for every frame's pose, the six landmarks and the odometry's stride and turn scales at once, from the
same odometry and sightings the filters get, but with oracle association: each sighting is tied to the landmark
it really shows (from the simulator's ``Measurement.source``) and look-alikes and false positives are left out.
So it answers "how close does the online EKF get to the best an offline solver can do with perfect association".
Training side only: ``naoslam`` never imports GTSAM.
"""
from __future__ import annotations

import gtsam
import numpy as np

from naoslam.measurement import Measurement
from naoslam.motion import OdometryModel, VelocityModel
from naoslam.runner import Sequence, SlamResult
from naoslam.sim import CONFUSED_SOURCE, FALSE_POSITIVE_SOURCE, LOOKALIKE_SOURCE

LABEL = "GTSAM smoother (oracle association)"
_FINITE_STEP = 1e-6


def true_identity(m: Measurement) -> str | None:
    """The landmark a sighting really shows (a UTIAS barcode is its identity), or None for a simulated look-alike
    or false positive."""
    if m.source.startswith(CONFUSED_SOURCE):
        return m.source[len(CONFUSED_SOURCE):]
    return None if m.source in (LOOKALIKE_SOURCE, FALSE_POSITIVE_SOURCE) else m.signature


def smooth(sequence: Sequence, stride_scale_std: float = 0.3, turn_scale_std: float = 0.1,
           pose_std: float = 0.01) -> SlamResult:
    """Batch-optimise a measurement-level sequence: a simulated walk or a UTIAS log (one pose per frame)."""
    graph, initial = gtsam.NonlinearFactorGraph(), gtsam.Values()
    scales = gtsam.symbol("s", 0)
    graph.add(gtsam.PriorFactorPoint2(scales, np.ones(2), gtsam.noiseModel.Diagonal.Sigmas(
        np.array([stride_scale_std, turn_scale_std]))))
    initial.insert(scales, np.ones(2))
    pose = sequence.start.copy()
    keys, times, truth, odometry = [], [], [], []
    pending: list[np.ndarray] = []
    seen: set[str] = set()
    for event in sequence.events:
        if event.control is not None:
            pending.append(event.control)
            pose = sequence.motion.move(pose, event.control)
        if keys and event.measurements is None:
            continue
        key = gtsam.symbol("x", len(keys))
        initial.insert(key, gtsam.Pose2(*pose))
        if keys:
            graph.add(_odometry_factor(keys[-1], key, scales, pending, sequence.motion))
        else:
            graph.add(gtsam.PriorFactorPose2(key, gtsam.Pose2(*sequence.start),
                                             gtsam.noiseModel.Isotropic.Sigma(3, pose_std)))
        pending = []
        keys.append(key)
        times.append(event.t)
        truth.append(event.true_pose)
        odometry.append(event.odometry_pose)
        for m in event.measurements or []:
            identity = true_identity(m)
            if identity is None:
                continue
            if identity not in sequence.landmarks_truth:
                continue
            landmark = gtsam.symbol("l", sorted(sequence.landmarks_truth).index(identity))
            if identity not in seen:
                seen.add(identity)
                heading = pose[2] + m.bearing_rad
                initial.insert(landmark, pose[:2] + m.range_m * np.array([np.cos(heading), np.sin(heading)]))
            noise = gtsam.noiseModel.Diagonal.Sigmas(np.array([m.bearing_std, m.range_std]))
            graph.add(gtsam.BearingRangeFactor2D(key, landmark, gtsam.Rot2.fromAngle(m.bearing_rad), m.range_m,
                                                 noise))
    values = gtsam.LevenbergMarquardtOptimizer(graph, initial).optimize()
    poses = np.array([[p.x(), p.y(), p.theta()] for p in (values.atPose2(k) for k in keys)])
    landmarks = {name: values.atPoint2(gtsam.symbol("l", i))
                 for i, name in enumerate(sorted(sequence.landmarks_truth)) if name in seen}
    stride, turn = values.atPoint2(scales)
    known = all(p is not None for p in truth)
    return SlamResult(LABEL, np.array(times), poses, np.array(truth) if known else None,
                      np.array(odometry) if known and all(o is not None for o in odometry) else None, landmarks,
                      sequence.landmarks_truth, None, odometry_scales=(float(stride), float(turn)))


def _relative_motion(controls: list[np.ndarray], motion: OdometryModel | VelocityModel, stride: float,
                     turn: float) -> np.ndarray:
    """The pose reached from the origin by the reported controls with the odometry scales applied."""
    pose = np.zeros(3)
    for u in controls:
        pose = motion.move(pose, motion.scaled(u, stride, turn))
    return pose


def _odometry_factor(previous, current, scales, controls: list[np.ndarray], motion: OdometryModel | VelocityModel):
    """Between factor whose measured motion depends on the scale variable (numeric Jacobians); its noise is the
    motion model's, propagated over the controls."""
    covariance = np.eye(3) * 1e-10
    pose = np.zeros(3)
    for u in controls:
        g, v = motion.jacobians(pose, u)
        covariance = g @ covariance @ g.T + v @ motion.control_noise(u) @ v.T
        pose = motion.move(pose, u)

    def error(this, values, jacobians):
        a, b = values.atPose2(this.keys()[0]), values.atPose2(this.keys()[1])
        s = values.atPoint2(this.keys()[2])

        def residual(a, b, s) -> np.ndarray:
            expected = gtsam.Pose2(*_relative_motion(controls, motion, s[0], s[1]))
            return gtsam.Pose2.Logmap(expected.between(a.between(b)))

        value = residual(a, b, s)
        if jacobians is not None:
            for slot, perturb in enumerate((
                    lambda d: residual(a.retract(d), b, s), lambda d: residual(a, b.retract(d), s),
                    lambda d: residual(a, b, s + d))):
                size = 2 if slot == 2 else 3
                columns = []
                for i in range(size):
                    step = np.zeros(size)
                    step[i] = _FINITE_STEP
                    columns.append((perturb(step) - perturb(-step)) / (2 * _FINITE_STEP))
                jacobians[slot] = np.stack(columns, axis=1)
        return value

    return gtsam.CustomFactor(gtsam.noiseModel.Gaussian.Covariance(covariance), [previous, current, scales], error)
