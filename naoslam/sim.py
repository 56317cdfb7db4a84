"""Simulated Nao walks on the SPL field with the six poles: true path, drifting odometry, noisy sightings.

Measurement level: range/bearing of every pole inside the camera's field of view and range, with relative range
noise (the reported standard deviation follows the *measured* range, as a real front end's must), bearing noise,
misses, class confusions, one-off false positives (a random class at a random place in view) and persistent
look-alikes (a pole of some class standing where no landmark of that class is, seen like a real one). The odometry
has per-step noise and a systematic bias (stride scale and turn bias), tuned so that dead reckoning alone drifts
about 0.5 m on average over a one-minute square, as the thesis's Nao did (0.50 m). The default walk, 90 s of the
square, goes once round and along one more side, so it closes its loop.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from naoslam.camera import NAO_HFOV_DEG
from naoslam.field import GUTMANN_LANDMARKS
from naoslam.landmarks import CLASSES
from naoslam.measurement import Measurement
from naoslam.motion import wrap

PATHS = ("square", "circle", "figure8")
#: ``Measurement.source`` of a simulated sighting that is not what it says: a look-alike pole, a one-off false
#: positive, or a real landmark reported with another class (``confused from yp``). Scoring and the smoother
#: reference read it; the filters never do.
LOOKALIKE_SOURCE = "look-alike"
FALSE_POSITIVE_SOURCE = "false positive"
CONFUSED_SOURCE = "confused from "


@dataclass(frozen=True)
class SimConfig:
    """A walk: path, duration and rates, sensor noise, and odometry error."""

    path: str = "square"
    duration_s: float = 90.0
    side_m: float = 2.4
    speed_m_s: float = 0.16
    turn_rad_s: float = 0.6
    odometry_hz: float = 10.0
    frame_hz: float = 5.0
    #: Frames per second the front end gets through (every frame_hz / front_end_hz-th camera frame; None: all), as
    #: a slower CPU would. The walk, its odometry and the frames kept are the same as at the full rate.
    front_end_hz: float | None = None
    hfov_deg: float = NAO_HFOV_DEG
    max_range_m: float = 6.0
    range_rel_std: float = 0.05
    bearing_std_deg: float = 1.5
    miss_rate: float = 0.1
    false_positive_rate: float = 0.05
    confusion_rate: float = 0.0
    lookalikes: int = 0
    stride_scale: float = 1.25
    turn_bias: float = 0.04
    odometry_noise: tuple[float, float] = (0.02, 0.02)
    seed: int = 0

    def odometry_alphas(self) -> tuple[float, float, float, float]:
        """Odometry-model noise that matches this walk's random odometry error (the bias is left to the
        filter's scale states): rotation per rotation and per translation, translation per translation and per
        rotation, as variance coefficients."""
        stride_noise, turn_noise = self.odometry_noise
        return (turn_noise ** 2, turn_noise ** 2, stride_noise ** 2, 1e-4)

    def __post_init__(self) -> None:
        if self.path not in PATHS:
            raise ValueError(f"path {self.path!r} is not one of {', '.join(PATHS)}")
        for name in ("false_positive_rate", "confusion_rate", "miss_rate"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"{name} {getattr(self, name)} must lie in 0..1")
        for name, value in (("duration_s", self.duration_s), ("stride_scale", self.stride_scale)):
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} {value:g} must be a positive finite number")
        if self.lookalikes < 0:
            raise ValueError(f"lookalikes {self.lookalikes} must be 0 or more")
        if self.front_end_hz is not None:
            every = self.frame_hz / self.front_end_hz if self.front_end_hz > 0 else 0.0
            if every < 1 or abs(every - round(every)) > 1e-6:
                raise ValueError(f"front_end_hz {self.front_end_hz:g}: give the camera's {self.frame_hz:g} Hz divided "
                                 f"by a whole number (e.g. {self.frame_hz / 2:g}, {self.frame_hz / 4:g})")

    @property
    def label(self) -> str:
        """The walk's name in reports: its path, and the front end's frame rate where one was set."""
        return f"sim {self.path}" + (f" at {self.front_end_hz:g} frames/s" if self.front_end_hz is not None else "")

    @property
    def frames_per_front_end_frame(self) -> int:
        """How many camera frames pass for each one the front end gets."""
        return 1 if self.front_end_hz is None else int(round(self.frame_hz / self.front_end_hz))


@dataclass
class SimStep:
    """One odometry tick: time, true pose, odometry pose, and the sightings of a frame taken then (or None)."""

    t: float
    true_pose: np.ndarray
    odometry_pose: np.ndarray
    measurements: list[Measurement] | None


@dataclass
class Walk:
    """The walk's steps, the six landmarks and the look-alikes (class, x, y) that the front end also sees."""

    steps: list[SimStep]
    landmarks: dict[str, tuple[float, float]]
    config: SimConfig
    lookalikes: list[tuple[str, float, float]]


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


def place_lookalikes(landmarks: dict[str, tuple[float, float]], config: SimConfig,
                     rng: np.random.Generator) -> list[tuple[str, float, float]]:
    """Look-alike poles inside the walk's area, at least 1 m from every landmark, each of a random class."""
    out: list[tuple[str, float, float]] = []
    reach = config.side_m / 2 + 1.5
    while len(out) < config.lookalikes:
        x, y = rng.uniform(-reach, reach, 2)
        if all(math.hypot(x - lx, y - ly) >= 1.0 for lx, ly in landmarks.values()):
            out.append((str(rng.choice(CLASSES)), float(x), float(y)))
    return out


def sightings(pose: np.ndarray, landmarks: dict[str, tuple[float, float]], config: SimConfig,
              rng: np.random.Generator, lookalikes: list[tuple[str, float, float]] = ()) -> list[Measurement]:
    """Noisy measurements of the poles (landmarks and look-alikes) in view: misses, confusions, false positives."""
    half_fov = math.radians(config.hfov_deg) / 2
    bearing_std = math.radians(config.bearing_std_deg)
    out = []
    poles = [(name, x, y, "sim") for name, (x, y) in landmarks.items()]
    poles += [(name, x, y, LOOKALIKE_SOURCE) for name, x, y in lookalikes]
    for name, x, y, source in poles:
        r = math.hypot(x - pose[0], y - pose[1])
        b = float(wrap(math.atan2(y - pose[1], x - pose[0]) - pose[2]))
        if r > config.max_range_m or abs(b) > half_fov or rng.random() < config.miss_rate:
            continue
        measured = max(0.05, r + rng.normal(0, config.range_rel_std * r))
        if rng.random() < config.confusion_rate:
            source = f"{CONFUSED_SOURCE}{name}" if source == "sim" else source
            name = str(rng.choice([c for c in CLASSES if c != name]))
        out.append(Measurement(measured, float(wrap(b + rng.normal(0, bearing_std))), name, 0.95,
                               config.range_rel_std * measured, bearing_std, source))
    if rng.random() < config.false_positive_rate:
        r = rng.uniform(0.5, config.max_range_m)
        out.append(Measurement(r, rng.uniform(-half_fov, half_fov), str(rng.choice(CLASSES)), 0.9,
                               config.range_rel_std * r, bearing_std, FALSE_POSITIVE_SOURCE))
    return out


def simulate(config: SimConfig = SimConfig(), landmarks: dict[str, tuple[float, float]] | None = None) -> Walk:
    """The walk: true poses from the path, odometry with noise and bias, a frame every 1/frame_hz seconds."""
    rng = np.random.default_rng(config.seed)
    landmarks = dict(landmarks or GUTMANN_LANDMARKS)
    lookalikes = place_lookalikes(landmarks, config, np.random.default_rng([config.seed, 1]))
    dt = 1.0 / config.odometry_hz
    frame_every = max(1, int(round(config.odometry_hz / config.frame_hz)))
    true_pose = _start(config)
    odometry = true_pose.copy()
    steps = [SimStep(0.0, true_pose.copy(), odometry.copy(), sightings(true_pose, landmarks, config, rng, lookalikes))]
    for i, (v, w) in enumerate(_commands(config), start=1):
        true_pose = np.array([true_pose[0] + v * dt * math.cos(true_pose[2]),
                              true_pose[1] + v * dt * math.sin(true_pose[2]), float(wrap(true_pose[2] + w * dt))])
        # What the robot believes it did: scaled stride, biased turns, random slip.
        ds = v * dt * config.stride_scale * (1 + rng.normal(0, config.odometry_noise[0]))
        dtheta = w * dt * (1 + config.turn_bias) + rng.normal(0, config.odometry_noise[1]) * (abs(w) + abs(v)) * dt
        odometry = np.array([odometry[0] + ds * math.cos(odometry[2]), odometry[1] + ds * math.sin(odometry[2]),
                             float(wrap(odometry[2] + dtheta))])
        seen = sightings(true_pose, landmarks, config, rng, lookalikes) if i % frame_every == 0 else None
        if seen is not None and (i // frame_every) % config.frames_per_front_end_frame:
            seen = None  # a frame the front end had no time for; drawn all the same, so the walk stays the same
        steps.append(SimStep(i * dt, true_pose, odometry, seen))
    return Walk(steps, landmarks, config, lookalikes)
