"""Frames a Nao would see along a simulated walk: the six poles at their field positions, one venue, ray-cast."""
from __future__ import annotations

import math
from functools import lru_cache

import cv2
import numpy as np

from detector.console import show_progress
from detector.parallel import default_workers, ordered_map
from detector.synth.effects import apply_camera_effects, camera_effects
from detector.synth.objects import pole
from detector.synth.render import render_scene
from detector.synth.scene import Scene, goal_posts, venue
from naoslam.camera import CameraPose, PinholeCamera
from naoslam.field import FieldGeometry
from naoslam.landmarks import PoleGeometry
from naoslam.sim import SimConfig, Walk, simulate

#: The head looks slightly down while walking, as the thesis's Nao did.
WALK_PITCH_DEG = 8.0
CAMERA_HEIGHT_M = 0.5

_EFFECTS = None


def _swaying_pose(walk: Walk, step: int, rng: np.random.Generator) -> CameraPose:
    """The camera on the true pose with a little walking sway in height, pitch and roll."""
    x, y, theta = walk.steps[step].true_pose
    return CameraPose(x, y, CAMERA_HEIGHT_M + rng.normal(0, 0.005), theta,
                      math.radians(WALK_PITCH_DEG + rng.normal(0, 1.0)), math.radians(rng.normal(0, 1.5)))


@lru_cache(maxsize=4)
def simulated_walk(path: str, seed: int) -> Walk:
    """The measurement-level walk ``poles slam --sim PATH --seed SEED`` runs (default settings), made once per
    process."""
    return simulate(SimConfig(path=path, seed=seed))


@lru_cache(maxsize=4)
def walk_frame_steps(path: str, seed: int) -> tuple[int, ...]:
    """The steps of :func:`simulated_walk`'s walk that take a frame, found once per process."""
    return tuple(frame_steps(simulated_walk(path, seed)))


def frame_steps(walk: Walk) -> list[int]:
    """Indices of the walk's steps that take a frame."""
    return [i for i, s in enumerate(walk.steps) if s.measurements is not None]


def walk_scene(walk: Walk, step: int, seed: int, camera: PinholeCamera) -> Scene:
    """The scene at one step: the swaying camera, the poles and look-alikes, the goals."""
    rng = np.random.default_rng([seed, step])
    lighting, room = venue(np.random.default_rng([seed, 0xF1E1D]))
    pose = _swaying_pose(walk, step, rng)
    scene = Scene(camera, pose, lighting, room, effects_seed=int(rng.integers(2**31)), jpeg_quality=90)
    scene.cylinders = [pole(code, px, py, PoleGeometry()) for code, (px, py) in walk.landmarks.items()]
    scene.cylinders += [pole(code, px, py, PoleGeometry()) for code, px, py in walk.lookalikes]
    scene.cylinders += goal_posts(FieldGeometry())
    return scene


def _render(args: tuple[Walk, int, int, PinholeCamera]) -> np.ndarray:
    global _EFFECTS
    if _EFFECTS is None:
        _EFFECTS = camera_effects()
    scene = walk_scene(*args)
    image = (render_scene(scene).image * 255.0 + 0.5).astype(np.uint8)
    image = apply_camera_effects(_EFFECTS, image, scene.effects_seed)
    return cv2.cvtColor(image, cv2.COLOR_RGB2BGR)


def render_walk(walk: Walk, seed: int = 0, camera: PinholeCamera = PinholeCamera(), workers: int | None = None,
                progress: bool = True) -> list[np.ndarray]:
    """BGR frames at every step of the walk that has a frame (where the measurement-level sim has sightings)."""
    steps = frame_steps(walk)
    frames = ordered_map(_render, [(walk, i, seed, camera) for i in steps], workers or default_workers(len(steps)))
    return list(show_progress(frames, "rendering the walk", "frame", total=len(steps), enabled=progress))


def walk_camera_poses(walk: Walk, seed: int = 0) -> list[CameraPose]:
    """The camera pose of every frame :func:`render_walk` renders (what the robot's joint angles would give)."""
    return [_swaying_pose(walk, i, np.random.default_rng([seed, i])) for i in frame_steps(walk)]
