"""Where a real backdrop's floor is, so composited objects stand on it and behind what stands nearer.

A photo has no depth, but a camera above a flat floor gives one for free: something standing on the floor is
nearer the lower its foot lies in the image. ``read_floor`` models the floor's colour from the frame's bottom strip
(robust median and spread in Lab), keeps the floor-coloured region that reaches the bottom edge (closed, so field
lines and small marks count as floor) and, per column, finds the nearest thing standing on it: the run of non-floor
pixels just above the floor that reaches the bottom, unless the floor goes on above it (then it is a line or a mark
lying on the floor, or too small to matter: balls are lost with the lines). The scene sampler then only puts a
pole's foot on the floor and keeps the horizon above it; the renderer hides an object wherever such a run stands
lower (nearer) than the object's own foot. Labels stay exact: the hidden pixels leave the masks.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import cv2
import numpy as np

from detector.synth.backdrops import load_backdrop

#: Share of the frame's rows whose colour defines the floor.
FLOOR_STRIP = 0.06
#: Chi-square (3 dof, 95 %) bound on the normalised colour distance of a floor pixel.
FLOOR_DISTANCE2 = 7.81
#: Smallest spread (Lab units: lightness, a, b) a floor colour is allowed: an even carpet still admits its noise, and
#: lightness most, which shading and vignetting change far more than hue.
MIN_SPREAD = (12.0, 3.0, 3.0)
#: Closing size as a share of the frame width: fills field lines and small marks on the floor.
CLOSE_SHARE = 1 / 40
#: A thing stands in front of an object only when its foot lies this many rows below the object's.
FRONT_MARGIN_PX = 3
#: The nearest the floor's far edge (a wall, furniture) may be to the camera, in metres: bounds the pitch from above.
NEAREST_FAR_EDGE_M = 1.0


@dataclass(frozen=True)
class FloorMap:
    """A backdrop's floor (bool per pixel), the top row of the floor per column (height: none in that column), the
    row where the floor ends (the far edge, which the horizon lies above) and the nearest standing thing per column:
    its mask and its foot row (-1: nothing stands in that column)."""

    floor: np.ndarray
    floor_top: np.ndarray
    far_edge: float
    front: np.ndarray
    front_foot: np.ndarray

    @property
    def height(self) -> int:
        return self.floor.shape[0]

    def stands_at(self, u: float, v: float) -> bool:
        """Whether a foot at pixel (u, v) can stand there: below the frame, on the floor's visible part (beside the
        frame: the edge column's), or hidden behind something standing nearer but still below the floor's far edge."""
        if v >= self.height:
            return True
        column = min(max(int(round(u)), 0), self.floor.shape[1] - 1)
        if v >= self.floor_top[column] - FRONT_MARGIN_PX:
            return True
        row = int(v)
        return self.far_edge <= row and bool(self.front[row, column]) and self.front_foot[column] > v + FRONT_MARGIN_PX

    def in_front_of(self, foot_row: float) -> np.ndarray:
        """Pixels of the frame that stand nearer than an object whose foot lies at ``foot_row``."""
        nearer = self.front_foot > foot_row + FRONT_MARGIN_PX
        return self.front & nearer[None, :]


def read_floor(image: np.ndarray) -> FloorMap:
    """The floor model of one RGB float frame (0..1)."""
    height, width = image.shape[:2]
    lab = cv2.cvtColor(cv2.GaussianBlur(image.astype(np.float32), (5, 5), 0), cv2.COLOR_RGB2Lab)
    strip = lab[height - max(2, round(FLOOR_STRIP * height)):, width // 10 : width - width // 10].reshape(-1, 3)
    centre, spread = _floor_colour(strip)
    candidate = (((lab - centre) / spread) ** 2).sum(axis=-1) < FLOOR_DISTANCE2
    size = max(3, round(width * CLOSE_SHARE)) | 1
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size, size))
    closed = cv2.morphologyEx(candidate.astype(np.uint8), cv2.MORPH_CLOSE, kernel)
    _, labels = cv2.connectedComponents(closed, connectivity=4)
    touching = np.unique(labels[-1][closed[-1] > 0])
    floor = np.isin(labels, touching) & (closed > 0)
    floor_top = np.where(floor.any(axis=0), floor.argmax(axis=0), height)
    # Nearest thing per column: the first non-floor run above the floor that reaches the bottom edge.
    floor_to_bottom = np.cumprod(floor[::-1], axis=0)[::-1].astype(bool)
    run_bottom = height - 1 - floor_to_bottom.sum(axis=0)  # -1: the column is floor all the way up
    beyond = np.arange(height)[:, None] > run_bottom[None, :]
    run = np.cumprod((~floor | beyond)[::-1], axis=0)[::-1].astype(bool) & ~beyond
    # A run with floor above it lies on the floor (a field line, a mark) or is too small to matter: it hides nothing.
    flat = run.any(axis=0) & (floor_top < run.argmax(axis=0))
    run[:, flat] = False
    run_bottom[flat] = -1
    visible_tops = floor_top[floor_top < height]
    far_edge = float(np.percentile(visible_tops, 10)) if visible_tops.size else float(height)
    return FloorMap(floor, floor_top.astype(np.int32), far_edge, run, run_bottom.astype(np.int32))


def _floor_colour(strip: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centre and spread of the floor's Lab colour: median and MAD, then mean and s.d. of the pixels near them
    (a robot or a ball in the strip moves neither)."""
    centre = np.median(strip, axis=0)
    spread = np.maximum(1.4826 * np.median(np.abs(strip - centre), axis=0), MIN_SPREAD)
    inliers = strip[(((strip - centre) / spread) ** 2).sum(axis=-1) < FLOOR_DISTANCE2]
    if len(inliers) >= 0.25 * len(strip):
        centre, spread = inliers.mean(axis=0), np.maximum(inliers.std(axis=0), MIN_SPREAD)
    return centre, spread


@lru_cache(maxsize=8)
def floor_of(path: Path) -> FloorMap:
    """The floor model of a backdrop file (as ``load_backdrop`` reads it), cached like the frame itself."""
    return read_floor(load_backdrop(path))


def pitch_range_deg(floor: FloorMap, focal_px: float, cy: float, camera_height_m: float,
                    allowed: tuple[float, float]) -> tuple[float, float]:
    """Camera pitches (deg, down positive) within ``allowed`` that put the horizon above the floor's top edge but
    no further above it than a wall 1 m away would (the floor seen must end somewhere past the robot's feet)."""
    lowest = floor.far_edge - FRONT_MARGIN_PX
    highest = lowest - focal_px * camera_height_m / NEAREST_FAR_EDGE_M
    low = math.degrees(math.atan((cy - lowest) / focal_px))
    high = math.degrees(math.atan((cy - highest) / focal_px))
    low, high = max(low, allowed[0]), min(high, allowed[1])
    if low > high:  # the frame looks further down or up than the sampler allows: keep the nearest allowed pitch
        nearest = min(max(low, allowed[0]), allowed[1])
        return nearest, nearest
    return low, high
