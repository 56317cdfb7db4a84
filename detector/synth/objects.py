"""Scene primitives that the renderer ray-casts: cylinders (poles, tubes, goal posts) and textured quads."""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

RGB = tuple[float, float, float]

#: Surface colours in sRGB 0..1: landmark bands and the white base.
PINK: RGB = (0.93, 0.27, 0.63)
BLUE: RGB = (0.25, 0.65, 0.90)
YELLOW: RGB = (0.95, 0.85, 0.18)
GREEN: RGB = (0.18, 0.68, 0.33)
WHITE: RGB = (0.93, 0.93, 0.90)
BAND_RGB: dict[str, RGB] = {"p": PINK, "b": BLUE, "y": YELLOW, "g": GREEN}


def tilt_rotation(lean: float, lean_direction: float) -> np.ndarray:
    """World-from-local rotation of an axis leaning ``lean`` rad from vertical towards azimuth ``lean_direction``."""
    axis = np.array([-math.sin(lean_direction), math.cos(lean_direction), 0.0])
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(lean) * k + (1 - math.cos(lean)) * (k @ k)


def horizontal_rotation(azimuth: float) -> np.ndarray:
    """World-from-local rotation for a cylinder lying on the ground, its axis along ``azimuth``."""
    along = np.array([math.cos(azimuth), math.sin(azimuth), 0.0])
    side = np.array([-math.sin(azimuth), math.cos(azimuth), 0.0])
    return np.stack([side, np.array([0.0, 0.0, 1.0]), along], axis=1)


@dataclass
class Cylinder:
    """An open tube: bottom centre ``base``, local z along its axis, coloured ``bands`` of (z0, z1, rgb).

    ``label`` is the landmark class for a pole, None for a distractor.
    """

    base: np.ndarray
    rotation: np.ndarray
    radius: float
    length: float
    bands: tuple[tuple[float, float, RGB], ...]
    label: str | None = None

    def corners(self) -> np.ndarray:
        """The 8 corners of the local bounding box, in the world."""
        r, h = self.radius, self.length
        local = np.array([[x, y, z] for x in (-r, r) for y in (-r, r) for z in (0.0, h)])
        return self.base + local @ self.rotation.T

    def point_on_axis(self, height: float) -> np.ndarray:
        return self.base + self.rotation[:, 2] * height


@dataclass
class Quad:
    """A flat textured rectangle: centre, in-plane unit axes (u right, v down the texture), half sizes, texture (H, W, 3)."""

    centre: np.ndarray
    axis_u: np.ndarray
    axis_v: np.ndarray
    half_u: float
    half_v: float
    texture: np.ndarray

    def corners(self) -> np.ndarray:
        return np.array([self.centre + su * self.half_u * self.axis_u + sv * self.half_v * self.axis_v
                         for su in (-1, 1) for sv in (-1, 1)])


def pole(code: str, x: float, y: float, geometry, rotation: np.ndarray | None = None,
         paint: dict[str, RGB] = BAND_RGB) -> Cylinder:
    """A landmark cylinder: white base, then the bottom band, then the top band (``code`` names top first).

    ``paint`` maps each band letter to its colour (the nominal paints unless a scene varies them).
    """
    base_h, band = geometry.base_height, geometry.band_height
    bands = ((0.0, base_h, WHITE), (base_h, base_h + band, paint[code[1]]),
             (base_h + band, base_h + 2 * band, paint[code[0]]))
    return Cylinder(np.array([x, y, 0.0]), np.eye(3) if rotation is None else rotation,
                    geometry.radius, geometry.height, bands, label=code)


def repainted(landmark: Cylinder, paint: dict[str, RGB]) -> Cylinder:
    """The landmark (a ``pole``) with its two coloured bands in ``paint``; shape, place and white base kept."""
    base, lower, upper = landmark.bands
    code = landmark.label
    return replace(landmark, bands=(base, (*lower[:2], paint[code[1]]), (*upper[:2], paint[code[0]])))
