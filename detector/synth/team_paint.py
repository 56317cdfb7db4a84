"""A team's own band paint, measured from its annotated frames (``poles synth --paint-from EXPORT``).

Each outline is cut along the pole's axis in the pole's own proportions (``PoleGeometry``: a band is 105/90 of the
diameter tall, the white base two bands): the middle of the top band, of the bottom band and of the base, each in the
middle half of the pole's width so no background or edge pixel counts. A band's paint is its colour white-balanced
against the base of the same pole (linear light: band / base * the renderer's white), so the light of the room the
frame was taken in is taken out; a pole whose base is not in view keeps its band colour unbalanced.
The renderer paints every pole of a frame with one colour per band letter, so each letter's paint is the median over
every band of that letter (both classes and both positions); the per-class medians are kept for the report.
"""
from __future__ import annotations

import colorsys
import math
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from detector.datasets.intake import open_dataset
from detector.datasets.io import decode_frame
from detector.datasets.model import Instance
from detector.records import JsonRecord
from detector.synth.objects import BAND_RGB, RGB, WHITE
from naoslam.landmarks import PoleGeometry

#: Along the axis, in band heights from the top of the outline: the stretch of each part that is measured.
PART_SPANS = {"top": (0.25, 0.75), "bottom": (1.25, 1.75), "base": (2.3, 3.6)}
#: Half the measured width, as a share of the pole's width: the middle half.
HALF_WIDTH_SHARE = 0.25
#: Fewest pixels a part needs to be measured (a pole about 8 px wide has about this many in a band's middle).
MIN_PART_PIXELS = 6


@dataclass(frozen=True)
class TeamPaint(JsonRecord):
    """Measured paint: RGB 0..1 per band letter (``measured`` says which letters any pole showed; the others keep the
    renderer's nominal paint), per class and band position, and how many poles were measured and skipped."""

    letters: dict[str, RGB]
    measured: dict[str, int]
    classes: dict[str, dict[str, RGB]] = field(default_factory=dict)
    poles: int = 0
    skipped: int = 0

    def scene_paint(self) -> tuple[tuple[str, RGB], ...]:
        """The paint as ``SceneConfig.team_paint`` takes it."""
        return tuple(sorted(self.letters.items()))

    def hue_degrees(self, letter: str) -> float:
        return colorsys.rgb_to_hsv(*self.letters[letter])[0] * 360.0


class NoPaintMeasured(ValueError):
    """An export none of whose poles is large enough to measure (or that labels none)."""


def measure_team_paint(export: str | Path, splits: tuple[str, ...] = ("train", "valid"),
                       geometry: PoleGeometry = PoleGeometry()) -> TeamPaint:
    """Measure the band paint of every annotated pole in ``export``'s ``splits`` (the held-out test split is never
    looked at). Refuses an export in which no pole is large enough to measure."""
    dataset = open_dataset(export, progress=False)
    samples = [s for split in splits for s in dataset.split(split)] or dataset.split("test")
    bands: dict[str, list[np.ndarray]] = {letter: [] for letter in BAND_RGB}
    per_class: dict[str, dict[str, list[np.ndarray]]] = {}
    poles = skipped = 0
    for sample in samples:
        if not sample.instances:
            continue
        image = cv2.cvtColor(decode_frame(sample.image), cv2.COLOR_BGR2RGB).astype(np.float64) / 255.0
        for instance in sample.instances:
            paint = pole_paint(image, instance, geometry)
            if paint is None:
                skipped += 1
                continue
            poles += 1
            for part, letter in (("top", instance.cls[0]), ("bottom", instance.cls[1])):
                bands[letter].append(paint[part])
                per_class.setdefault(instance.cls, {}).setdefault(part, []).append(paint[part])
    if not poles:
        raise NoPaintMeasured(f"{export}: no annotated pole is large enough to measure its paint (each band needs "
                              f"{MIN_PART_PIXELS} pixels) - annotate nearer poles, or leave out --paint-from")
    letters = {letter: _median_rgb(values) if values else BAND_RGB[letter] for letter, values in bands.items()}
    classes = {cls: {part: _median_rgb(values) for part, values in parts.items()}
               for cls, parts in sorted(per_class.items())}
    return TeamPaint(letters, {letter: len(values) for letter, values in bands.items()}, classes, poles, skipped)


def _median_rgb(colours: list[np.ndarray]) -> RGB:
    """The median colour, to four decimals (as the renderer records the paint it was given)."""
    red, green, blue = (round(float(c), 4) for c in np.median(colours, axis=0))
    return red, green, blue


def pole_paint(image: np.ndarray, instance: Instance, geometry: PoleGeometry = PoleGeometry()) -> dict[str, RGB] | None:
    """The white-balanced paint of one pole's ``top`` and ``bottom`` bands (``image``: RGB float 0..1), or None when
    the outline is too small or too short to hold both bands."""
    height, width = image.shape[:2]
    outline = instance.pixels(width, height).astype(np.float32)
    (cx, cy), (w, h), angle = cv2.minAreaRect(outline)
    axis = np.array([math.cos(math.radians(angle)), math.sin(math.radians(angle))])
    if w > h:  # the long side is the pole's axis
        w, h = h, w
    else:
        axis = np.array([-axis[1], axis[0]])
    if axis[1] > 0:  # point the axis up the pole (towards smaller y)
        axis = -axis
    band_px = w * geometry.band_height / geometry.diameter
    if h < 1.9 * band_px:
        return None
    mask = np.zeros((height, width), np.uint8)
    cv2.fillPoly(mask, [np.round(outline).astype(np.int32)], 1)
    ys, xs = np.nonzero(mask)
    offset = np.stack([xs - cx, ys - cy], axis=1)
    top = h / 2.0 - offset @ axis  # distance below the top end of the outline, along the axis
    across = np.abs(offset @ np.array([-axis[1], axis[0]]))
    middle = across <= HALF_WIDTH_SHARE * w
    parts = {}
    for part, (start, end) in PART_SPANS.items():
        inside = middle & (top >= start * band_px) & (top <= end * band_px)
        if inside.sum() >= MIN_PART_PIXELS:
            parts[part] = np.median(image[ys[inside], xs[inside]], axis=0)
    if "top" not in parts or "bottom" not in parts:
        return None
    base = parts.get("base")
    return {part: _balanced(parts[part], base) for part in ("top", "bottom")}


def _balanced(band: np.ndarray, base: np.ndarray | None) -> RGB:
    """``band`` white-balanced against ``base`` in linear light, as sRGB 0..1 (unchanged without a base)."""
    if base is None or np.min(base) <= 0.02:
        return tuple(float(c) for c in band)
    linear = _to_linear(band) / _to_linear(base) * _to_linear(np.asarray(WHITE))
    return tuple(float(c) for c in _to_srgb(np.clip(linear, 0.0, 1.0)))


def _to_linear(srgb: np.ndarray) -> np.ndarray:
    return np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4)


def _to_srgb(linear: np.ndarray) -> np.ndarray:
    return np.where(linear <= 0.0031308, linear * 12.92, 1.055 * linear ** (1 / 2.4) - 0.055)
