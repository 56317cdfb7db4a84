"""The colour-filter front end of the 2024 thesis (section 3.3.1), the baseline the detector must beat.

HSV ranges for pink, blue, yellow, green and white are turned once into a lookup table indexed by the quantised
BGR value (Luijten's trick), so a frame is classified with one table lookup and no colour conversion. Then, for
each pink segment: look from its centre straight down and up at distance d = 1.2 x its longest half-extent, then at
growing angles (2, 4, ... 60 deg) either side, for blue, yellow or green; then below the lower of the two bands
look for white. A pink + colour + white chain is a landmark. Beyond the thesis, the second band and the white are
taken only inside the pink band's footprint moved one band length that way, so the green carpet or a white field
line behind the pole is not mistaken for part of it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from naoslam.camera import CameraPose
from naoslam.perception.detections import Detection
from naoslam.perception.frames import bgr_frame
from naoslam.ground import GroundView
from naoslam.measurement import RangeCalibration

#: OpenCV HSV ranges (H 0..179): (hue ranges, minimum saturation, maximum saturation, minimum value).
HSV_RANGES: dict[str, tuple[tuple[tuple[int, int], ...], int, int, int]] = {
    "p": (((145, 179), (0, 4)), 90, 255, 70),
    "b": (((88, 118),), 90, 255, 60),
    "y": (((18, 38),), 90, 255, 80),
    "g": (((45, 90),), 80, 255, 50),
    "w": (((0, 179),), 0, 60, 70),
}
BITS = {name: 1 << i for i, name in enumerate(HSV_RANGES)}
SECOND_COLOURS = ("b", "y", "g")
#: Bits kept per BGR channel in the lookup table (6: 64^3 entries, 256 KiB).
LUT_BITS = 6


def build_lookup(ranges=HSV_RANGES, bits: int = LUT_BITS) -> np.ndarray:
    """Colour bitmask for every quantised BGR value, evaluated at the centre of its bin."""
    levels = 1 << bits
    step = 256 // levels
    centres = (np.arange(levels) * step + step // 2).astype(np.uint8)
    b, g, r = np.meshgrid(centres, centres, centres, indexing="ij")
    bgr = np.stack([b, g, r], axis=-1).reshape(-1, 1, 3)
    hsv = cv2.cvtColor(bgr, cv2.COLOR_BGR2HSV).reshape(-1, 3).astype(int)
    lut = np.zeros(len(hsv), np.uint8)
    for name, (hues, s_min, s_max, v_min) in ranges.items():
        hue_ok = np.zeros(len(hsv), bool)
        for low, high in hues:
            hue_ok |= (hsv[:, 0] >= low) & (hsv[:, 0] <= high)
        ok = hue_ok & (hsv[:, 1] >= s_min) & (hsv[:, 1] <= s_max) & (hsv[:, 2] >= v_min)
        lut[ok] |= BITS[name]
    return lut


@dataclass(frozen=True)
class Segment:
    """A connected region of pink: its pixels, centre and vertical extent."""

    mask: np.ndarray
    cx: float
    cy: float
    top: int
    bottom: int


class ColourFilter:
    """Finds pink + (blue | yellow | green) + white chains in BGR frames (a ``PoleDetector``: every detection has
    confidence 1 and is placed by its band-dividing point; its ranges come from a calibration's colour law)."""

    matching = "point"
    stored_conf = None

    def __init__(self, min_area_px: int = 12, max_angle_deg: int = 60, angle_step_deg: int = 2):
        self.conf = 1.0
        self._calibration: RangeCalibration | None = None
        self.lut = build_lookup()
        self.min_area_px = min_area_px
        self.angles = [0] + [a for step in range(angle_step_deg, max_angle_deg + 1, angle_step_deg) for a in (step, -step)]
        self._shift = 8 - LUT_BITS

    def classify(self, frame: np.ndarray) -> np.ndarray:
        """Per-pixel colour bitmask (see ``BITS``) by table lookup."""
        q = (frame >> self._shift).astype(np.int32)
        return self.lut[(q[..., 0] << (2 * LUT_BITS)) | (q[..., 1] << LUT_BITS) | q[..., 2]]

    @property
    def calibration(self) -> RangeCalibration:
        """The shipped model's calibration, whose colour law is the colour filter's on the Nao's camera."""
        if self._calibration is None:
            # Deferred: reading the shipped model's metadata loads onnxruntime, which the filter alone never needs.
            from naoslam.perception.pole_model import shipped_calibration

            self._calibration = self.check_calibration(shipped_calibration())
        return self._calibration

    @property
    def usable_calibration(self) -> RangeCalibration:
        return self.calibration

    def check_calibration(self, calibration: RangeCalibration | None) -> RangeCalibration:
        """``calibration`` when it has a colour law, else a ValueError that says how to get one."""
        if calibration is None or calibration.colour_law is None:
            raise ValueError("the colour filter needs a colour law and the calibration has none: leave the "
                             "calibration out to use the shipped one, or fit one with `poles calibrate` on poles of "
                             "known range")
        return calibration

    def __call__(self, frame: np.ndarray, camera_pose: CameraPose | None = None,
                 view: GroundView | None = None) -> list[Detection]:
        """Every pink + colour + white chain in a BGR frame, as a detection of confidence 1 whose mask is its two
        bands, whose band centres are given and whose column is their midpoint's. The thesis's filter scans the
        whole frame: the camera's pose and ground view are not used."""
        frame = bgr_frame(frame)
        colours = self.classify(frame)
        pink = (colours & BITS["p"]) > 0
        found = []
        for segment, window in self._segments(pink):
            # Everything about one candidate happens inside the window where its bands and base can lie.
            masks = {name: (colours[window] & bit) > 0 for name, bit in BITS.items()}
            second = self._second_band(segment, masks)
            if second is None:
                continue
            name, band, step = second
            lower = band if step[1] > 0 else segment.mask
            if not self._white_below(lower, step, masks["w"]):
                continue
            upper_mask, lower_mask = (segment.mask, band) if step[1] > 0 else (band, segment.mask)
            origin = (window[1].start, window[0].start)
            full = np.zeros(pink.shape, bool)
            full[window] = upper_mask | lower_mask
            centres = (_centre(upper_mask, origin), _centre(lower_mask, origin))
            found.append(Detection.from_mask("p" + name if step[1] > 0 else name + "p", 1.0, full,
                                             centre_column=(centres[0][0] + centres[1][0]) / 2, band_centres=centres))
        return found

    def _segments(self, mask: np.ndarray) -> list[tuple[Segment, tuple[slice, slice]]]:
        """Pink segments, each in its own window (coordinates inside it): the segment's box grown by three band
        lengths up and down (the other band and the white base) and by as much sideways (the probe's angles)."""
        count, labels, stats, centroids = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=8)
        out = []
        for i in range(1, count):
            x, y, w, h, area = (int(v) for v in stats[i])
            if area < self.min_area_px:
                continue
            reach = 3 * h + 2
            window = (slice(max(0, y - reach), min(mask.shape[0], y + h + reach)),
                      slice(max(0, x - reach), min(mask.shape[1], x + w + reach)))
            top, left = window[0].start, window[1].start
            out.append((Segment(labels[window] == i, float(centroids[i][0]) - left, float(centroids[i][1]) - top,
                                y - top, y + h - 1 - top), window))
        return out

    def _probe(self, cx: float, cy: float, d: float, directions: tuple[int, ...], shape: tuple[int, int]):
        """Points at distance d from (cx, cy): down (+1) and/or up (-1), at growing angles either side."""
        for angle in self.angles:
            dx, dy = d * math.sin(math.radians(angle)), d * math.cos(math.radians(angle))
            for direction in directions:
                x, y = int(round(cx + dx)), int(round(cy + direction * dy))
                if 0 <= x < shape[1] and 0 <= y < shape[0]:
                    yield x, y, (dx, direction * dy)

    def _second_band(self, pink: Segment, masks: dict[str, np.ndarray]):
        """The thesis's probe search from the pink centre, then the band itself: pixels of the colour found in the
        pink band's own footprint moved one band length that way (a band is as large as the pink one, so the
        green carpet behind a green band is not taken for it)."""
        d = 1.2 * max(pink.cy - pink.top, pink.bottom - pink.cy, 1.0)
        for x, y, step in self._probe(pink.cx, pink.cy, d, (1, -1), pink.mask.shape):
            for name in SECOND_COLOURS:
                if masks[name][y, x]:
                    band = _shifted(pink.mask, step, pink.bottom - pink.top + 1) & masks[name]
                    if band.sum() >= 0.3 * pink.mask.sum():
                        return name, band, step
        return None

    def _white_below(self, band: np.ndarray, step: tuple[float, float], white: np.ndarray) -> bool:
        """White in the footprint one band length below the lower band (the base is twice as long)."""
        down = (step[0], abs(step[1]))
        height = int(np.ptp(np.flatnonzero(band.any(axis=1)))) + 1
        return bool((_shifted(band, down, height) & white).sum() >= 0.2 * band.sum())


def _centre(mask: np.ndarray, origin: tuple[int, int] = (0, 0)) -> tuple[float, float]:
    """Mean pixel position of a mask whose (0, 0) lies at ``origin`` (x, y) of the frame."""
    ys, xs = np.nonzero(mask)
    return float(xs.mean()) + origin[0], float(ys.mean()) + origin[1]


def _shifted(mask: np.ndarray, direction: tuple[float, float], length: float) -> np.ndarray:
    """The mask moved ``length`` pixels along ``direction``."""
    norm = math.hypot(*direction) or 1.0
    shift = np.float32([[1, 0, direction[0] / norm * length], [0, 1, direction[1] / norm * length]])
    moved = cv2.warpAffine(mask.astype(np.uint8), shift, mask.shape[::-1], flags=cv2.INTER_NEAREST)
    return moved > 0
