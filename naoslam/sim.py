"""Simulated Nao walks on the SPL field with the six poles: true path, drifting odometry, noisy sightings.

Measurement level: range/bearing of every pole inside the camera's field of view and range, with relative range
noise, bearing noise, misses and false positives (a random class at a random place in view). The odometry has
per-step noise and a systematic bias (stride scale and turn bias), tuned so that dead reckoning alone drifts
about 0.5 m on average over a one-minute square, as the thesis's Nao did (0.50 m).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from naoslam.field import GUTMANN_LANDMARKS
from naoslam.landmarks import CLASSES
from naoslam.measurement import Measurement
from naoslam.motion import wrap

PATHS = ("square", "circle", "figure8")


@dataclass(frozen=True)
class SimConfig:
    """A walk: path, duration and rates, sensor noise, and odometry error."""

    path: str = "square"
    duration_s: float = 60.0
    side_m: float = 2.4
    speed_m_s: float = 0.16
    turn_rad_s: float = 0.6
    odometry_hz: float = 10.0
    frame_hz: float = 5.0
    hfov_deg: float = 56.3
    max_range_m: float = 6.0
    range_rel_std: float = 0.05
    bearing_std_deg: float = 1.5
    miss_rate: float = 0.1
    false_positive_rate: float = 0.05
    stride_scale: float = 1.25
    turn_bias: float = 0.04
    odometry_noise: tuple[float, float] = (0.02, 0.02)
    seed: int = 0

    def __post_init__(self) -> None:
        if self.path not in PATHS:
            raise ValueError(f"path {self.path!r} is not one of {', '.join(PATHS)}")


@dataclass
class SimStep:
    """One odometry tick: time, true pose, odometry pose, and the sightings of a frame taken then (or None)."""

    t: float
    true_pose: np.ndarray
    odometry_pose: np.ndarray
    measurements: list[Measurement] | None


@dataclass
class Walk:
    steps: list[SimStep]
    landmarks: dict[str, tuple[float, float]]
    config: SimConfig


def _commands(config: SimConfig) -> list[tuple[float, float]]:
    """(forward speed, turn rate) per odometry tick for the chosen path."""
    dt = 1.0 / config.odometry_hz
    ticks = int(config.duration_s * config.odometry_hz)
    if config.path == "circle":
        return [(config.speed_m_s, config.speed_m_s / (config.side_m / 2))] * ticks
    if config.path == "figure8":
        half = int(2 * math.pi * (config.side_m / 2) / config.speed_m_s / dt)
        w = config.speed_m_s / (config.side_m / 2)
        return [(config.speed_m_s, w if (i // half) % 2 == 0 else -w) for i in range(ticks)]
    edge = int(config.side_m / config.speed_m_s / dt)
    turn = int(round((math.pi / 2) / config.turn_rad_s / dt))
    cycle = [(config.speed_m_s, 0.0)] * edge + [(0.0, (math.pi / 2) / (turn * dt))] * turn
    return [cycle[i % len(cycle)] for i in range(ticks)]


def _start(config: SimConfig) -> np.ndarray:
    if config.path == "square":
        return np.array([-config.side_m / 2, -config.side_m / 2, 0.0])
    return np.array([0.0, -config.side_m / 2, 0.0])


def sightings(pose: np.ndarray, landmarks: dict[str, tuple[float, float]], config: SimConfig,
              rng: np.random.Generator) -> list[Measurement]:
    """Noisy measurements of the poles in view, with misses and false positives."""
    half_fov = math.radians(config.hfov_deg) / 2
    bearing_std = math.radians(config.bearing_std_deg)
    out = []
    for name, (x, y) in landmarks.items():
        r = math.hypot(x - pose[0], y - pose[1])
        b = float(wrap(math.atan2(y - pose[1], x - pose[0]) - pose[2]))
        if r > config.max_range_m or abs(b) > half_fov or rng.random() < config.miss_rate:
            continue
        range_std = config.range_rel_std * r
        out.append(Measurement(max(0.05, r + rng.normal(0, range_std)), float(wrap(b + rng.normal(0, bearing_std))),
                               name, 0.95, range_std, bearing_std, "sim"))
    if rng.random() < config.false_positive_rate:
        r = rng.uniform(0.5, config.max_range_m)
        out.append(Measurement(r, rng.uniform(-half_fov, half_fov), str(rng.choice(CLASSES)), 0.9,
                               config.range_rel_std * r, bearing_std, "false positive"))
    return out


def simulate(config: SimConfig = SimConfig(), landmarks: dict[str, tuple[float, float]] | None = None) -> Walk:
    """The walk: true poses from the path, odometry with noise and bias, a frame every 1/frame_hz seconds."""
    rng = np.random.default_rng(config.seed)
    landmarks = dict(landmarks or GUTMANN_LANDMARKS)
    dt = 1.0 / config.odometry_hz
    frame_every = max(1, int(round(config.odometry_hz / config.frame_hz)))
    true_pose = _start(config)
    odometry = true_pose.copy()
    steps = [SimStep(0.0, true_pose.copy(), odometry.copy(), sightings(true_pose, landmarks, config, rng))]
    for i, (v, w) in enumerate(_commands(config), start=1):
        true_pose = np.array([true_pose[0] + v * dt * math.cos(true_pose[2]),
                              true_pose[1] + v * dt * math.sin(true_pose[2]), float(wrap(true_pose[2] + w * dt))])
        # What the robot believes it did: scaled stride, biased turns, random slip.
        ds = v * dt * config.stride_scale * (1 + rng.normal(0, config.odometry_noise[0]))
        dtheta = w * dt * (1 + config.turn_bias) + rng.normal(0, config.odometry_noise[1]) * (abs(w) + abs(v)) * dt
        odometry = np.array([odometry[0] + ds * math.cos(odometry[2]), odometry[1] + ds * math.sin(odometry[2]),
                             float(wrap(odometry[2] + dtheta))])
        seen = sightings(true_pose, landmarks, config, rng) if i % frame_every == 0 else None
        steps.append(SimStep(i * dt, true_pose, odometry, seen))
    return Walk(steps, landmarks, config)
