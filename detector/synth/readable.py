"""Whether a rendered band shows the colour its label names, read from the finished frame's pixels.

Varied paint, a backdrop's colour cast, back light and the camera's white balance can together turn a blue band green
in the pixels. Such a pole's label is true of the world but cannot be read from the frame, so no model can learn it:
the renderer draws those frames again (``generate.render_one``). A band's colour is read as the hue of its coloured
pixels and named by the nearest of the colour filter's hue ranges (``naoslam.perception.colour_filter.HSV_RANGES``), the same
boxes the varied paint is drawn in. A band too dark or too grey to carry a hue gives no verdict: it contradicts no
label.
"""
from __future__ import annotations

import cv2
import numpy as np

from naoslam.perception.colour_filter import HSV_RANGES

#: A pixel carries a hue when its OpenCV saturation and value reach these (below them the hue is mostly noise).
MIN_SATURATION = 60
MIN_VALUE = 40
#: A band is read only when this many of its pixels, and this share of them, carry a hue.
MIN_HUED_PIXELS = 12
MIN_HUED_SHARE = 0.25
BAND_LETTERS = ("p", "b", "y", "g")
HUE_TURN = 180  # OpenCV hue units in a full turn


def band_colour(image_rgb: np.ndarray, band_mask: np.ndarray) -> str | None:
    """The band letter whose hue range lies nearest the band's mean hue, or None when too few pixels carry a hue.

    ``image_rgb`` is the finished uint8 RGB frame and ``band_mask`` a boolean mask of the band's visible pixels.
    """
    pixels = image_rgb[band_mask]
    if len(pixels) == 0:
        return None
    hsv = cv2.cvtColor(pixels.reshape(-1, 1, 3), cv2.COLOR_RGB2HSV).reshape(-1, 3).astype(np.float64)
    hued = (hsv[:, 1] >= MIN_SATURATION) & (hsv[:, 2] >= MIN_VALUE)
    if hued.sum() < max(MIN_HUED_PIXELS, MIN_HUED_SHARE * len(pixels)):
        return None
    angles = hsv[hued, 0] * (2 * np.pi / HUE_TURN)
    hue = float(np.arctan2(np.sin(angles).mean(), np.cos(angles).mean()) * HUE_TURN / (2 * np.pi)) % HUE_TURN
    return min(BAND_LETTERS, key=lambda letter: _distance_to_range(hue, HSV_RANGES[letter][0]))


def misread_bands(image_rgb: np.ndarray, code: str, band_masks: tuple[np.ndarray, ...]) -> list[str]:
    """The letters of a pole's bands (``code``, top band first, as ``band_masks``) that read as another colour."""
    return [letter for letter, mask in zip(code, band_masks)
            if band_colour(image_rgb, mask) not in (None, letter)]


def _distance_to_range(hue: float, ranges: tuple[tuple[int, int], ...]) -> float:
    """Hue distance (round the circle) from ``hue`` to the nearest of ``ranges``; 0 inside one."""
    distances = []
    for low, high in ranges:
        if low <= hue <= high:
            return 0.0
        distances += [_circular(hue - low), _circular(hue - high)]
    return min(distances)


def _circular(difference: float) -> float:
    difference = abs(difference) % HUE_TURN
    return min(difference, HUE_TURN - difference)
