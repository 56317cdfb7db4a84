"""Band paint that varies between poles and prints, yet always stays the colour it names.

What still counts as pink, blue, yellow or green is defined once, by the colour filter's HSV ranges
(``naoslam.perception.colour_filter.HSV_RANGES``); varied paint is drawn inside that box, spread across it.
"""
from __future__ import annotations

import colorsys
from dataclasses import dataclass
from functools import cache

import numpy as np

from detector.synth.objects import BAND_RGB, RGB
from naoslam.perception.colour_filter import HSV_RANGES


@dataclass(frozen=True)
class PaintBox:
    """An HSV box, each axis 0..1; ``hue`` may run past 1 (wrapping through red)."""

    hue: tuple[float, float]
    saturation: tuple[float, float]
    value: tuple[float, float]

    @property
    def hue_width(self) -> float:
        return self.hue[1] - self.hue[0]


@cache
def paint_box(letter: str) -> PaintBox:
    """The colour filter's HSV range for a band colour as a box in 0..1."""
    hues, s_min, s_max, v_min = HSV_RANGES[letter]
    low, high = hues[0]
    if len(hues) > 1:  # pink: (145..179) and (0..4) are one range wrapping through red
        high = hues[1][1] + 180
    inside = 0.5  # half a filter step in from every edge, so 8-bit rounding cannot push a colour out
    return PaintBox(hue=((low + inside) / 180, (high - inside) / 180),
                    saturation=((s_min + inside) / 255, (s_max - inside) / 255), value=((v_min + inside) / 255, 1.0))


@dataclass(frozen=True)
class PaintVariation:
    """How one pole's band colours are drawn: hue around the nominal paint (s.d. ``hue_spread`` of its box's hue
    width, drawn again if it leaves the box), saturation and value scaled by uniform factors and kept in the box."""

    hue_spread: float = 0.25
    saturation: tuple[float, float] = (0.55, 1.1)
    value: tuple[float, float] = (0.3, 1.05)

    def draw(self, rng: np.random.Generator) -> dict[str, RGB]:
        """One pole's band colours, by band letter."""
        paint = {}
        for letter, rgb in BAND_RGB.items():
            box = paint_box(letter)
            hue, saturation, value = colorsys.rgb_to_hsv(*rgb)
            hue = _hue_inside(rng, _unwrap(hue, box.hue), self.hue_spread * box.hue_width, box.hue) % 1.0
            saturation = float(np.clip(saturation * rng.uniform(*self.saturation), *box.saturation))
            value = float(np.clip(value * rng.uniform(*self.value), box.value[0], 1.0))
            paint[letter] = colorsys.hsv_to_rgb(hue, saturation, value)
        return paint


def _hue_inside(rng: np.random.Generator, centre: float, sd: float, hue_range: tuple[float, float],
                tries: int = 100) -> float:
    """A normal draw around ``centre``, drawn again while it falls outside ``hue_range`` (no pile-up at the edges);
    after ``tries`` misses (a centre outside the range, or a huge spread) the centre clipped into the range."""
    for _ in range(tries):
        hue = centre + rng.normal(0.0, sd)
        if hue_range[0] <= hue <= hue_range[1]:
            return hue
    return float(np.clip(centre, *hue_range))


def _unwrap(hue: float, hue_range: tuple[float, float]) -> float:
    """``hue`` moved by a full turn if that brings it inside a range that wraps past 1."""
    return hue + 1.0 if hue < hue_range[0] and hue + 1.0 <= hue_range[1] else hue
