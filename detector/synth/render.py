"""Render a scene to an image with exact per-pole visible masks, ranges, bearings and band geometry."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from detector.synth.backdrops import Look, composite
from detector.synth.background import render_background
from detector.synth.floor import FloorMap
from detector.synth.objects import Cylinder, Quad
from detector.synth.raycast import Hit, cast_cylinder, cast_quad, world_rays
from detector.synth.scene import Scene, foot_pixel
from naoslam.landmarks import PoleGeometry

#: A pole is named only when each coloured band shows (in the frame, unhidden) at least this many pixels or this share
#: of its silhouette: its class is the pair of band colours, so a white base or one band alone cannot be named, by a
#: model or a person.
MIN_BAND_PIXELS = 30
MIN_BAND_SHARE = 0.25


@dataclass
class PoleTruth:
    """Ground truth of one landmark in a frame: what is visible of it and where it is."""

    cls: str
    mask: np.ndarray
    range_m: float
    bearing_rad: float
    visible_fraction: float
    partial: bool
    band_divide_px: tuple[float, float]
    band_centre_distance_px: float
    position_m: tuple[float, float]
    #: Pixels of the upper and the lower coloured band's whole silhouette (uncut, unhidden).
    band_pixels_whole: tuple[int, ...]
    #: The visible pixels of the upper and the lower coloured band, as masks over the frame.
    band_masks: tuple[np.ndarray, ...]
    #: Index of the pole's cylinder in ``Scene.cylinders``.
    cylinder: int

    @property
    def band_pixels_shown(self) -> tuple[int, ...]:
        """Visible pixels of the upper and the lower coloured band."""
        return tuple(int(mask.sum()) for mask in self.band_masks)

    @property
    def nameable(self) -> bool:
        """Whether enough of both coloured bands shows for anyone to tell the class (``MIN_BAND_PIXELS``/``_SHARE``)."""
        return all(shown >= min(MIN_BAND_PIXELS, MIN_BAND_SHARE * whole)
                   for shown, whole in zip(self.band_pixels_shown, self.band_pixels_whole))


@dataclass
class Frame:
    """A rendered frame: RGB float image in 0..1 (before camera effects) and the poles' truths."""

    image: np.ndarray
    poles: list[PoleTruth]


def render_scene(scene: Scene, geometry: PoleGeometry = PoleGeometry(), backdrop: np.ndarray | None = None,
                 look: Look | None = None, floor: FloorMap | None = None) -> Frame:
    """Ray-cast the background, every quad and cylinder with a depth test; masks are what stays visible.

    With a ``backdrop`` (a real frame of the camera's size, RGB 0..1) the objects are drawn over it in ``look``
    instead of over the modelled room. With its ``floor`` as well, whatever the frame shows standing nearer than an
    object hides that object (and leaves its mask); without it the masks do not depend on the frame.
    """
    cam, pose = scene.camera, scene.pose
    if backdrop is None:
        colour, depth = render_background(pose.position, world_rays((0, 0, cam.width, cam.height), pose, cam),
                                          scene.room, scene.lighting)
    else:
        colour = np.zeros((cam.height, cam.width, 3), np.float32)
        depth = np.full((cam.height, cam.width), np.inf, np.float32)
    owner = np.full((cam.height, cam.width), -1, np.int32)
    objects = [*scene.quads, *scene.cylinders]
    hits = [cast_quad(obj, pose, cam, scene.lighting) if isinstance(obj, Quad) else cast_cylinder(obj, pose, cam, scene.lighting)
            for obj in objects]
    for index, hit in enumerate(hits):
        if hit is not None:
            _composite(hit, index, colour, depth, owner)
    if floor is not None:
        _hide_behind_frame_content(scene, objects, floor, owner)
    poles = []
    for index, cylinder in enumerate(objects):
        if isinstance(cylinder, Quad) or cylinder.label is None:
            continue
        visible = owner == index
        if not visible.any():
            continue
        full = cast_cylinder(cylinder, pose, cam, scene.lighting, clip=False)
        full_area = int(full.mask.sum()) if full is not None else 0
        in_image_area = _in_image_area(full, cam.width, cam.height)
        range_m, bearing = pose.range_bearing_to(float(cylinder.base[0]), float(cylinder.base[1]))
        divide = _project(scene, cylinder.point_on_axis(geometry.divide_height))
        upper = _project(scene, cylinder.point_on_axis(geometry.divide_height + geometry.band_height / 2))
        lower = _project(scene, cylinder.point_on_axis(geometry.divide_height - geometry.band_height / 2))
        band_masks = _band_masks(cylinder, hits[index], visible)
        band_pixels_whole = tuple(full.band_pixels(z0, z1) if full is not None else 0 for z0, z1 in _bands(cylinder))
        poles.append(PoleTruth(cylinder.label, visible, range_m, bearing, float(visible.sum()) / max(full_area, 1),
                               in_image_area < full_area, divide, float(math.dist(upper, lower)),
                               (float(cylinder.base[0]), float(cylinder.base[1])),
                               band_pixels_whole, band_masks, index - len(scene.quads)))
    if backdrop is not None:
        colour = composite(backdrop, colour, owner >= 0, look)
    return Frame(np.clip(colour, 0.0, 1.0), poles)


def _composite(hit: Hit, index: int, colour: np.ndarray, depth: np.ndarray, owner: np.ndarray) -> None:
    h, w = hit.mask.shape
    region = (slice(hit.v0, hit.v0 + h), slice(hit.u0, hit.u0 + w))
    nearer = hit.mask & (hit.depth < depth[region])
    colour[region][nearer] = hit.colour[nearer]
    depth[region][nearer] = hit.depth[nearer]
    owner[region][nearer] = index


def _hide_behind_frame_content(scene: Scene, objects: list, floor: FloorMap, owner: np.ndarray) -> None:
    """Give back to the frame every object pixel that the frame shows standing nearer than the object's foot."""
    for index, obj in enumerate(objects):
        shown = owner == index
        if not shown.any():
            continue
        foot = obj.base if isinstance(obj, Cylinder) else obj.centre
        _, foot_row = foot_pixel(scene.pose, scene.camera, foot[0], foot[1])  # behind the camera: below the frame
        owner[shown & floor.in_front_of(foot_row)] = -1


def _bands(cylinder: Cylinder) -> list[tuple[float, float]]:
    """The axis heights of the coloured bands above the base, top band first."""
    return [(z0, z1) for z0, z1, _ in reversed(cylinder.bands[1:])]


def _band_masks(cylinder: Cylinder, hit: Hit, visible: np.ndarray) -> tuple[np.ndarray, ...]:
    """The visible pixels of each coloured band (top first) as masks over the frame."""
    h, w = hit.mask.shape
    region = (slice(hit.v0, hit.v0 + h), slice(hit.u0, hit.u0 + w))
    masks = []
    for z0, z1 in _bands(cylinder):
        mask = np.zeros_like(visible)
        mask[region] = hit.mask & (hit.axial >= z0) & (hit.axial <= z1) & visible[region]
        masks.append(mask)
    return tuple(masks)


def _in_image_area(hit: Hit | None, width: int, height: int) -> int:
    if hit is None:
        return 0
    h, w = hit.mask.shape
    rows = slice(max(0, -hit.v0), max(0, min(h, height - hit.v0)))
    cols = slice(max(0, -hit.u0), max(0, min(w, width - hit.u0)))
    return int(hit.mask[rows, cols].sum())


def _project(scene: Scene, point: np.ndarray) -> tuple[float, float]:
    u, v = scene.camera.project(scene.pose.to_camera(point))
    return float(u), float(v)
