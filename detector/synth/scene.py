"""Random scenes: a Nao camera somewhere on the field, poles and look-alike distractors in view, a lit room."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from detector.synth.backdrops import BACKLIGHT_SHARE, Look
from detector.synth.background import Room, WallFeature
from detector.synth.floor import FloorMap, pitch_range_deg
from detector.synth.objects import (BAND_RGB, PINK, RGB, WHITE, YELLOW, Cylinder, Quad, horizontal_rotation, pole,
                                    tilt_rotation)
from detector.synth.paint import PaintVariation
from detector.synth.raycast import Lighting
from naoslam.camera import CameraPose, PinholeCamera
from naoslam.field import FieldGeometry
from naoslam.landmarks import CLASSES, PoleGeometry


@dataclass(frozen=True)
class SceneConfig:
    """Ranges the scene sampler draws from. Angles in degrees, distances in metres."""

    pole: PoleGeometry = PoleGeometry()
    camera_height: tuple[float, float] = (0.45, 0.55)
    pitch_deg: tuple[float, float] = (-2.0, 22.0)
    max_roll_deg: float = 7.0
    range_m: tuple[float, float] = (0.4, 9.0)
    max_poles: int = 4
    p_no_pole: float = 0.12
    p_lean: float = 0.15
    max_lean_deg: float = 12.0
    max_distractors: int = 4
    view_margin_deg: float = 6.0
    #: How printed paint varies between poles and prints, in the scenes that vary it.
    paint: PaintVariation = PaintVariation()
    #: Share of scenes whose poles keep the nominal paint (the rest vary it): fresh prints and the look a model
    #: already knows stay as common as worn, dull or off-hue ones.
    nominal_paint_share: float = 0.5
    #: A team's own paint (band letter, RGB) measured by ``team_paint.measure_team_paint``: when given, the poles of
    #: ``team_paint_share`` of the scenes wear it instead of the nominal or varied paint.
    team_paint: tuple[tuple[str, RGB], ...] = ()
    team_paint_share: float = 1.0
    #: Share of scenes whose poles all stand within ``far_range_m`` (6-18 px wide at 640x480): far poles seen more
    #: often in training. The draw is made only when the share is above 0, so the default frames stay the same.
    far_share: float = 0.0
    far_range_m: tuple[float, float] = (3.0, 9.0)
    #: Share of the frames drawn over a backdrop whose objects are back-lit: darkened to 25-60 % and hazed towards
    #: the frame's mean colour, as in front of a window. The ray-cast rooms light their objects themselves.
    backlight_share: float = BACKLIGHT_SHARE

    def __post_init__(self) -> None:
        for option, share in (("--nominal-paint-share", self.nominal_paint_share), ("--far-share", self.far_share),
                              ("the team paint share", self.team_paint_share),
                              ("--backlight-share", self.backlight_share)):
            if not 0.0 <= share <= 1.0:
                raise ValueError(f"{option} {share} must lie between 0 and 1")


@dataclass(frozen=True)
class BackdropShot:
    """A real frame a scene is drawn over and the look its objects take in that frame."""

    path: Path
    look: Look


@dataclass
class Scene:
    """Everything needed to render one frame deterministically (over ``backdrop`` when it has one)."""

    camera: PinholeCamera
    pose: CameraPose
    lighting: Lighting
    room: Room
    cylinders: list[Cylinder] = field(default_factory=list)
    quads: list[Quad] = field(default_factory=list)
    effects_seed: int = 0
    jpeg_quality: int = 90
    backdrop: BackdropShot | None = None


def sample_scene(rng: np.random.Generator, camera: PinholeCamera, config: SceneConfig = SceneConfig(),
                 goal_posts_in_view: bool = True, floor: FloorMap | None = None) -> Scene:
    """A random field scene with 0..max_poles landmarks in or near the view and some distractors.

    ``goal_posts_in_view=False`` leaves the field's goals out (a real backdrop has its own). With the ``floor`` of
    a real backdrop the camera's pitch keeps the horizon above that floor and every object's foot stands on it.
    """
    x, y, height, yaw = rng.uniform(-4.5, 4.5), rng.uniform(-3.0, 3.0), rng.uniform(*config.camera_height), \
        rng.uniform(-math.pi, math.pi)
    pitch_deg = config.pitch_deg if floor is None else \
        pitch_range_deg(floor, camera.focal_px, camera.cy, height, config.pitch_deg)
    pose = CameraPose(x=x, y=y, z=height, yaw=yaw, pitch=math.radians(rng.uniform(*pitch_deg)),
                      roll=math.radians(rng.normal(0.0, config.max_roll_deg / 2.5)))
    scene = Scene(camera, pose, _lighting(rng), _room(rng), effects_seed=int(rng.integers(2**31)),
                  jpeg_quality=int(rng.integers(60, 96)))
    occupied: list[tuple[float, float]] = []
    n_poles = 0 if rng.random() < config.p_no_pole else int(rng.integers(1, config.max_poles + 1))
    vary_paint = rng.random() >= config.nominal_paint_share
    team_paint = bool(config.team_paint) and (config.team_paint_share >= 1.0 or rng.random() < config.team_paint_share)
    pole_range_m = config.far_range_m if config.far_share > 0 and rng.random() < config.far_share else config.range_m
    for _ in range(n_poles):
        spot = _free_spot(rng, pose, camera, config, occupied, floor, pole_range_m)
        if spot is None:
            continue
        lean = None
        if rng.random() < config.p_lean:
            lean = tilt_rotation(math.radians(rng.uniform(2, config.max_lean_deg)), rng.uniform(-math.pi, math.pi))
        code = str(rng.choice(CLASSES))  # before the paint: drawing in another order would change every seed's frames
        paint = dict(config.team_paint) if team_paint else config.paint.draw(rng) if vary_paint else BAND_RGB
        scene.cylinders.append(pole(code, *spot, config.pole, lean, paint=paint))
    for _ in range(int(rng.integers(0, config.max_distractors + 1))):
        spot = _free_spot(rng, pose, camera, config, occupied, floor, config.range_m)
        if spot is not None:
            _add_distractor(rng, scene, spot, pose)
    if goal_posts_in_view:
        scene.cylinders += goal_posts(FieldGeometry())
    return scene


#: Camera roll of a calibration shot, drawn in +-this (deg): a pole tilted in the image by a degree or two has a
#: rotated box 0.5-1.5 px wider than an upright one (the pixel staircase along its sides), as in every robot frame.
CALIBRATION_ROLL_DEG = 3.0


def calibration_scene(rng: np.random.Generator, camera: PinholeCamera, code: str, range_m: float, angle_deg: float,
                      config: SceneConfig = SceneConfig()) -> Scene:
    """One upright pole at a known range and bearing, the camera nearly level and upright, like the thesis's
    calibration photos. The camera stands 4.5 m behind the field's centre, so a pole 9 m ahead is still inside the
    smallest room (whose walls stand at least 5.5 m from the centre) and not hidden behind its wall."""
    pose = CameraPose(x=-4.5, y=0.0, z=float(np.mean(config.camera_height)), yaw=0.0,
                      pitch=math.radians(rng.uniform(0, 4)),
                      roll=math.radians(rng.uniform(-CALIBRATION_ROLL_DEG, CALIBRATION_ROLL_DEG)))
    scene = Scene(camera, pose, _lighting(rng), _room(rng), effects_seed=int(rng.integers(2**31)), jpeg_quality=92)
    angle = math.radians(angle_deg)
    scene.cylinders.append(pole(code, pose.x + range_m * math.cos(angle), pose.y + range_m * math.sin(angle), config.pole))
    return scene


def goal_posts(f: FieldGeometry) -> list[Cylinder]:
    """The two goals' posts and crossbars (white cylinders): real look-alikes on every SPL field."""
    r, h, half = f.goal_post_diameter / 2, f.goal_height, f.goal_width / 2
    white = ((0.0, 10.0, WHITE),)
    posts = [Cylinder(np.array([sx * (f.length / 2 + r), sy * half, 0.0]), np.eye(3), r, h, white)
             for sx in (-1, 1) for sy in (-1, 1)]
    bars = [Cylinder(np.array([sx * (f.length / 2 + r), -half, h - r]), horizontal_rotation(math.pi / 2), r, 2 * half, white)
            for sx in (-1, 1)]
    return posts + bars


def _free_spot(rng, pose: CameraPose, camera: PinholeCamera, config: SceneConfig, occupied: list,
               floor: FloorMap | None, range_m: tuple[float, float]) -> tuple[float, float] | None:
    """A free floor spot in view, at a log-uniform distance within ``range_m``; None after 20 tries."""
    half_view = camera.hfov_deg / 2 + config.view_margin_deg
    low, high = np.log(range_m)
    for _ in range(20):
        distance = float(np.exp(rng.uniform(low, high)))
        bearing = pose.yaw + math.radians(rng.uniform(-half_view, half_view))
        x, y = pose.x + distance * math.cos(bearing), pose.y + distance * math.sin(bearing)
        if floor is not None and not floor.stands_at(*foot_pixel(pose, camera, x, y)):
            continue
        if all(math.hypot(x - ox, y - oy) > 0.3 for ox, oy in occupied):
            occupied.append((x, y))
            return x, y
    return None


def foot_pixel(pose: CameraPose, camera: PinholeCamera, x: float, y: float) -> tuple[float, float]:
    """Where the ground point (x, y) appears in the image (u, v); behind the camera counts as below the frame."""
    point = pose.to_camera(np.array([x, y, 0.0]))
    if point[2] <= 1e-6:
        return camera.cx, math.inf
    u, v = camera.project(point)
    return float(u), float(v)


def venue(rng: np.random.Generator) -> tuple[Lighting, Room]:
    """A random room and its light: one venue, shared by every frame of a walk."""
    return _lighting(rng), _room(rng)


def _lighting(rng) -> Lighting:
    azimuth, elevation = rng.uniform(-math.pi, math.pi), math.radians(rng.uniform(25, 75))
    direction = np.array([math.cos(elevation) * math.cos(azimuth), math.cos(elevation) * math.sin(azimuth), math.sin(elevation)])
    return Lighting(direction, ambient=rng.uniform(0.35, 0.6), diffuse=rng.uniform(0.45, 0.8))


def _jitter(rng, rgb, amount: float = 0.06) -> tuple[float, float, float]:
    return tuple(float(np.clip(c + rng.normal(0, amount), 0, 1)) for c in rgb)  # type: ignore[return-value]


_WALL_PALETTE = [(0.85, 0.83, 0.78), (0.92, 0.92, 0.9), (0.6, 0.62, 0.65), (0.55, 0.65, 0.8), (0.75, 0.68, 0.55),
                 (0.35, 0.35, 0.38), (0.8, 0.75, 0.7)]


def _room(rng) -> Room:
    f = FieldGeometry()
    hx, hy = f.length / 2 + f.border, f.width / 2 + f.border
    room = Room(x_min=-hx - rng.uniform(0.3, 3), x_max=hx + rng.uniform(0.3, 3), y_min=-hy - rng.uniform(0.3, 3),
                y_max=hy + rng.uniform(0.3, 3), height=rng.uniform(2.5, 4.5),
                wall_rgb=tuple(_jitter(rng, _WALL_PALETTE[i]) for i in rng.integers(0, len(_WALL_PALETTE), 4)),
                carpet_rgb=_jitter(rng, (0.2, 0.5, 0.22), 0.04), floor_rgb=_jitter(rng, (0.5, 0.45, 0.4), 0.08),
                ceiling_rgb=_jitter(rng, (0.85, 0.85, 0.85), 0.05))
    for wall in range(4):
        span = (room.y_min, room.y_max) if wall < 2 else (room.x_min, room.x_max)
        if rng.random() < 0.35:  # a row of windows, daylight behind, maybe a curtain
            for u in np.arange(span[0] + 0.5, span[1] - 1.5, rng.uniform(1.8, 3.0)):
                width = rng.uniform(0.8, 1.5)
                room.features.append(WallFeature(wall, u, u + width, 0.9, 2.3, _jitter(rng, (1.6, 1.7, 1.8), 0.2), True))
                if rng.random() < 0.4:
                    room.features.append(WallFeature(wall, u, u + width * rng.uniform(0.3, 1), 0.8, 2.4,
                                                     _jitter(rng, (0.5, 0.45, 0.5), 0.2)))
        for _ in range(int(rng.integers(0, 6))):  # clutter near the floor, posters and doors higher up
            u = rng.uniform(*span)
            if rng.random() < 0.5:
                room.features.append(WallFeature(wall, u, u + rng.uniform(0.3, 1.5), 0.0, rng.uniform(0.3, 1.2),
                                                 tuple(rng.uniform(0.1, 0.9, 3))))
            else:
                colour = PINK if rng.random() < 0.25 else YELLOW if rng.random() < 0.25 else tuple(rng.uniform(0.1, 1, 3))
                z0 = rng.uniform(0.0, 1.5)
                room.features.append(WallFeature(wall, u, u + rng.uniform(0.4, 1.2), z0, z0 + rng.uniform(0.4, 1.2), colour))
    textures = (None, "brick", "gravel")
    room.wall_texture = tuple(textures[int(i)] for i in rng.integers(0, len(textures), 4))
    room.floor_texture = textures[int(rng.integers(0, len(textures)))]
    room.texture_tile_m = float(rng.uniform(0.5, 2.5))
    room.texture_strength = float(rng.uniform(0.2, 0.8))
    room.carpet_pile = float(rng.uniform(0.1, 0.5))
    return room


def _add_distractor(rng, scene: Scene, spot: tuple[float, float], pose: CameraPose) -> None:
    """White paper tubes, tubes with a single or non-landmark pair of bands, coloured paper, yellow tape, posters."""
    x, y = spot
    kind = rng.choice(["tube", "banded_tube", "goal_post", "paper", "tape", "poster"])
    if kind in ("tube", "banded_tube", "goal_post"):
        radius = 0.05 if kind == "goal_post" else rng.uniform(0.02, 0.06)
        length = 0.8 if kind == "goal_post" else rng.uniform(0.15, 0.6)
        bands: tuple = ((0.0, length, WHITE),)
        if kind == "banded_tube":
            colours = list(BAND_RGB.values()) + [(0.9, 0.2, 0.15), (0.6, 0.3, 0.7)]
            first = colours[int(rng.integers(len(colours)))]
            split = length * rng.uniform(0.4, 0.7)
            bands = ((0.0, split, WHITE), (split, length, first)) if rng.random() < 0.5 else \
                ((0.0, split, WHITE), (split, (split + length) / 2, first), ((split + length) / 2, length, YELLOW))
            if first == PINK and len(bands) == 3:  # pink next to yellow would be a real landmark (py)
                bands = ((0.0, split, WHITE), (split, length, PINK))
        lying = kind == "tube" and rng.random() < 0.4
        if lying:
            azimuth = rng.uniform(-math.pi, math.pi)
            rotation = horizontal_rotation(azimuth)
            base = np.array([x, y, radius]) - rotation[:, 2] * length / 2
        else:
            rotation, base = np.eye(3), np.array([x, y, 0.0])
        scene.cylinders.append(Cylinder(base, rotation, radius, length, bands))
        return
    facing = math.atan2(pose.y - y, pose.x - x) + rng.uniform(-0.6, 0.6)
    across = np.array([-math.sin(facing), math.cos(facing), 0.0])
    if kind in ("paper", "tape"):
        azimuth = rng.uniform(-math.pi, math.pi)
        u = np.array([math.cos(azimuth), math.sin(azimuth), 0.0])
        v = np.array([-math.sin(azimuth), math.cos(azimuth), 0.0])
        colour = YELLOW if kind == "tape" else [PINK, YELLOW, *BAND_RGB.values(), WHITE][int(rng.integers(7))]
        half_u, half_v = (rng.uniform(0.4, 1.2), rng.uniform(0.015, 0.025)) if kind == "tape" else \
            (rng.uniform(0.08, 0.2), rng.uniform(0.06, 0.15))
        texture = np.full((2, 2, 3), _jitter(rng, colour, 0.03), np.float32)
        scene.quads.append(Quad(np.array([x, y, 0.002]), u, v, half_u, half_v, texture))
        return
    half_u, half_v = rng.uniform(0.15, 0.5), rng.uniform(0.2, 0.5)
    scene.quads.append(Quad(np.array([x, y, half_v + rng.uniform(0, 0.3)]), across, np.array([0.0, 0.0, -1.0]),
                            half_u, half_v, _poster_texture(rng)))


def _poster_texture(rng) -> np.ndarray:
    """A poster of coloured blocks, pink and yellow often among them."""
    texture = np.empty((16, 12, 3), np.float32)
    texture[:] = _jitter(rng, (0.95, 0.95, 0.92), 0.05)
    for _ in range(int(rng.integers(2, 7))):
        r0, c0 = int(rng.integers(0, 14)), int(rng.integers(0, 10))
        colour = [PINK, YELLOW, tuple(rng.uniform(0, 1, 3))][int(rng.integers(3))]
        texture[r0 : r0 + int(rng.integers(2, 8)), c0 : c0 + int(rng.integers(2, 8))] = colour
    return texture
