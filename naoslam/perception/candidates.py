"""Stage one of the robot front end: cheap pole candidates at the camera's full resolution.

Every landmark carries a pink band over or under a blue, yellow or green one (the codes ``bp gp yp pb pg py``).
Sparse rows of the ground band (from the horizon, where the camera's pose gives it, to the frame's bottom; one sample
per pixel pair, the chroma resolution of the camera's YUYV) are sorted into loose pink, loose band colour and the
rest. Two kinds of anchor follow:

- a **junction**, where a pink sample lies straight above or below a band-colour sample: the line between a pole's two
  bands, found whatever else around it is pink; its run's width is the pole's width;
- a **pink blob**, the pink samples joined into blobs, for poles whose other band does not read as a colour (dark,
  hazed or back-lit paint): the blob's height or width gives the band's size.

Each anchor becomes a window around where its pole can stand, six bands tall and two wide; with the camera's pose
junctions come first, without it the two kinds take turns (a frame seen whole holds many junctions of clutter, and
half its poles are framed best by their pink band). The windows go to the crop network
(:mod:`naoslam.perception.two_stage`), which names the pole or rejects the window and regresses the pole's box. The
colour tests are loose on purpose - a window the network rejects costs a fraction of a millisecond, a pole without
one is lost.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from naoslam.ground import GroundView
from naoslam.landmarks import PoleGeometry

#: Loose colours in OpenCV's HSV (H 0..179): pink's (hue low, hue high) ranges, and one range from yellow over green
#: to blue for the other band, each with a minimum saturation and value. Looser than the colour filter's
#: (``naoslam.perception.colour_filter.HSV_RANGES``): dark, hazed and back-lit paint must still read.
PINK_HSV = (((135, 179), (0, 4)), 40, 20)
BAND_HSV = ((15, 128), 40, 15)
#: Frame rows per scanned row at 480 rows (scaled with the frame's height): a pole 9 m away shows bands 7 rows tall.
ROW_STEP_AT_480 = 4
#: Frame columns per scanned column: one per pixel pair, the chroma resolution of the camera's YUYV. (Scaled with the
#: frame's width, a 1280x960 frame scanned every fourth column opened a window on a photograph's tie that the crop
#: network took for a pole: the columns stay dense.)
COLUMN_STEP = 2
#: A frame narrower or lower than this many pixels shows no pole the grid could find (a pole's band spans a few rows
#: and columns even 9 m away): it has no candidates.
MIN_FRAME_SIDE = 8
#: Pink samples a blob needs on the scanned grid.
MIN_BLOB_SAMPLES = 2
#: Junction samples this close along a row (and on the next row) are one junction: noise and JPEG chroma break it.
JOIN_KERNEL = np.ones((2, 5), np.uint8)
#: An anchor wider than this many poles at its place (with the camera's pose) is not a pole's band: a pink wall.
MAX_WIDTH_RATIO = 3.0
#: Windows overlapping more than this (IoU) frame the same pole; the later one is dropped.
DUPLICATE_IOU = 0.5
#: Most candidates kept per frame (the first in the finder's order), with the camera's pose and without it: the crop
#: network's batch. With the pose the windows are ranked by their fit, so the cap reaches into a busy frame's poorer
#: fits; without it the whole frame is seen and each window costs the same time.
MAX_CANDIDATES, MAX_CANDIDATES_WITHOUT_POSE = 32, 24
#: Each kind's best windows looked at for overlaps, per window kept: the rest of a cluttered frame's hundreds of
#: anchors could only come after them.
RANKED_PER_KEPT = 4
#: With the pose, how much an anchor narrower than the pole its place predicts counts against it, against one as
#: much wider: a near pole's line between the bands, tilted or shaded, crosses a scanned row pair in pieces.
NARROW_ANCHOR_WEIGHT = 0.25
#: A band is about 1.17 times as tall as the pole is wide (10.5 cm over 9 cm).
BAND_PER_WIDTH = 1.17
#: The window, in band heights: its height, its width, and how far its top lies above the line between the bands.
WINDOW_HEIGHT, WINDOW_WIDTH, WINDOW_ABOVE_JUNCTION = 6.0, 2.0, 2.0


@dataclass(frozen=True)
class Candidate:
    """A window (x0, y0, x1, y1 in frame pixels, may reach outside the frame) that may hold a pole, the anchor it
    was built around (x0, y0, x1, y1) and its kind (``junction`` or ``pink``)."""

    window: tuple[float, float, float, float]
    anchor: tuple[int, int, int, int]
    kind: str


def window_at_junction(centre_x, junction_y, band) -> tuple:
    """The window (x0, y0, x1, y1) around a pole whose bands meet at (``centre_x``, ``junction_y``), ``band`` px tall
    each: one band above the upper band, and below the lower one the white base (two bands) and one more. Numbers or
    arrays of them."""
    top = junction_y - WINDOW_ABOVE_JUNCTION * band
    return (centre_x - WINDOW_WIDTH * band / 2, top, centre_x + WINDOW_WIDTH * band / 2, top + WINDOW_HEIGHT * band)


def cut_by_frame(box: tuple[float, float, float, float], frame_hw: tuple[int, int]) -> bool:
    """Whether a pole's box reaches the frame's top or bottom row: only part of its height shows."""
    return box[1] <= 1 or box[3] >= frame_hw[0] - 1


def window_around_box(box: tuple[float, float, float, float], frame_hw: tuple[int, int]) -> tuple[float, ...]:
    """The window the finder would draw around a pole with this box (x0, y0, x1, y1): its band a quarter of an uncut
    pole's height, or 1.17 widths where the frame's top or bottom cuts it, and its bands meeting one band below its
    top (three above its foot where the top is cut)."""
    x0, y0, x1, y1 = box
    band = BAND_PER_WIDTH * (x1 - x0) if cut_by_frame(box, frame_hw) else (y1 - y0) / 4
    junction = y1 - 3 * band if y0 <= 1 else y0 + band
    return window_at_junction((x0 + x1) / 2, junction, band)


def row_step(frame_height: int) -> int:
    """Frame rows per scanned row for a frame this tall."""
    return max(1, round(ROW_STEP_AT_480 * frame_height / 480))


def scan_grid_bgr(frame: np.ndarray, rows: slice) -> np.ndarray:
    """The scanned grid of a frame as BGR uint8: ``rows``, one sample per pixel pair. A BGR frame gives each pair's
    first pixel; a YUYV buffer (HxWx2) each pair's first luma with the pair's own chroma, converted as full-range
    BT.601 (``naoslam.perception.frames``)."""
    if frame.ndim == 3 and frame.shape[2] == 2:
        packed = frame[rows]
        ycrcb = np.empty((packed.shape[0], packed.shape[1] // 2, 3), np.uint8)
        ycrcb[..., 0] = packed[:, 0::2, 0]
        ycrcb[..., 1] = packed[:, 1::2, 1]  # V (Cr): every pixel pair's second byte
        ycrcb[..., 2] = packed[:, 0::2, 1]  # U (Cb): its first
        return cv2.cvtColor(ycrcb, cv2.COLOR_YCrCb2BGR)
    picked = frame[rows]  # OpenCV picks every pair's first pixel faster than numpy's strided copy
    return cv2.resize(picked, (picked.shape[1] // COLUMN_STEP, picked.shape[0]), interpolation=cv2.INTER_NEAREST)


def colour_masks(grid_bgr: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """255 where a BGR sample is loose pink, and where it is a loose band colour (blue, yellow or green)."""
    hsv = cv2.cvtColor(grid_bgr, cv2.COLOR_BGR2HSV)
    hues, s_min, v_min = PINK_HSV
    pink = _any_in_range(hsv, [((low, s_min, v_min), (high, 255, 255)) for low, high in hues])
    (low, high), s_min, v_min = BAND_HSV
    return pink, cv2.inRange(hsv, (low, s_min, v_min), (high, 255, 255))


def _any_in_range(hsv: np.ndarray, boxes: list[tuple[tuple[int, ...], tuple[int, ...]]]) -> np.ndarray:
    mask = None
    for low, high in boxes:
        part = cv2.inRange(hsv, low, high)
        mask = part if mask is None else cv2.bitwise_or(mask, part)
    return mask


def junction_mask(pink: np.ndarray, band: np.ndarray) -> np.ndarray:
    """255 on each scanned row whose sample is pink over a band colour on the next row, or a band colour over
    pink: the line between a pole's two bands."""
    out = np.zeros_like(pink)
    out[:-1] = (pink[:-1] & band[1:]) | (band[:-1] & pink[1:])
    return out


class CandidateFinder:
    """Junctions and pink blobs on a sparse full-resolution grid of the ground band, each as a window for the crop
    network.

    With the frame's ground view, a band's size at an anchor comes from the camera's pose: the line between the
    bands stands ``PoleGeometry.divide_height`` above the floor, a pink band's middle a quarter of a band above or
    below it, so the depth at which the anchor's ray meets that height gives the band's pixel size. An anchor whose
    ray does not come down to that height cannot be a pole's, and one far wider than a pole there (a pink wall) is
    dropped. Without a view, the anchor's own size gives the band's. Windows that overlap an earlier one by more
    than ``DUPLICATE_IOU`` are one pole's, and only the first is kept.
    """

    def __init__(self, max_candidates: int | None = None, pole: PoleGeometry = PoleGeometry()):
        if max_candidates is not None and max_candidates < 1:
            raise ValueError(f"max_candidates {max_candidates}: keep at least one candidate per frame")
        self.max_candidates = max_candidates
        self.pole = pole

    def __call__(self, frame: np.ndarray, view: GroundView | None = None) -> list[Candidate]:
        """Candidates in a BGR or YUYV frame, each kind best first (with a view: the anchor's width nearest a pole's
        there; without: the widest); with a ``view``, junctions first, then pink blobs, and only rows below the
        horizon are scanned; without one, a junction and a pink blob in turn."""
        if frame.shape[0] < MIN_FRAME_SIDE or frame.shape[1] < MIN_FRAME_SIDE:
            return []
        top = view.band_top() if view is not None else 0
        step = row_step(frame.shape[0])
        pink, band = colour_masks(scan_grid_bgr(frame, slice(top, frame.shape[0], step)))
        joined = cv2.morphologyEx(junction_mask(pink, band), cv2.MORPH_CLOSE, JOIN_KERNEL)
        looked_at = RANKED_PER_KEPT * self.cap(view is not None)
        ranked = [(kind, *(part[:looked_at] for part in self._windows(
                      kind, self._anchors(kind, _blobs(mask), top, step), view)))
                  for kind, mask in (("junction", joined), ("pink", pink))]
        kinds = np.array([kind for kind, windows, _ in ranked for _ in windows])
        windows = np.concatenate([windows for _, windows, _ in ranked])
        anchors = np.concatenate([anchors for _, _, anchors in ranked])
        if not len(windows):
            return []
        if view is None:
            order = _interleaved(len(ranked[0][1]), len(ranked[1][1]))
            kinds, windows, anchors = kinds[order], windows[order], anchors[order]
        sizes = windows[:, 2:] - windows[:, :2]
        ranks = (len(windows) - np.arange(len(windows))).astype(float)  # earlier is better
        kept = cv2.dnn.NMSBoxes(np.concatenate([windows[:, :2], sizes], 1).tolist(), ranks.tolist(), 0.0,
                                DUPLICATE_IOU)
        kept = np.sort(np.asarray(kept, int).reshape(-1))[: self.cap(view is not None)]
        return [Candidate(tuple(window), tuple(anchor), str(kind)) for window, anchor, kind in
                zip(windows[kept].tolist(), anchors[kept].astype(int).tolist(), kinds[kept])]

    def cap(self, with_pose: bool) -> int:
        """The most candidates a frame keeps: the one asked for, else ``MAX_CANDIDATES`` with the pose and
        ``MAX_CANDIDATES_WITHOUT_POSE`` without it."""
        if self.max_candidates is not None:
            return self.max_candidates
        return MAX_CANDIDATES if with_pose else MAX_CANDIDATES_WITHOUT_POSE

    @staticmethod
    def _anchors(kind: str, blobs: np.ndarray, top: int, step: int) -> np.ndarray:
        """Each blob's anchor in frame pixels (x0, y0, x1, y1); a junction lies between its row and the next."""
        if not len(blobs):
            return np.zeros((0, 4))
        x, y, w, h, _ = blobs.astype(float).T
        rows = np.ones_like(h) if kind == "junction" else h
        return np.stack([x * COLUMN_STEP, top + y * step + (step / 2 if kind == "junction" else 0),
                         (x + w) * COLUMN_STEP, top + (y + rows) * step - (step / 2 if kind == "junction" else 0)], 1)

    def _windows(self, kind: str, anchors: np.ndarray, view: GroundView | None) -> tuple[np.ndarray, np.ndarray]:
        """The anchors' windows (N, 4) and the anchors, best first: sized by the pose where there is a view, else by
        the anchors."""
        if not len(anchors):
            return np.zeros((0, 4)), anchors
        centre_x, centre_y = (anchors[:, 0] + anchors[:, 2]) / 2, (anchors[:, 1] + anchors[:, 3]) / 2
        widths, heights = anchors[:, 2] - anchors[:, 0], anchors[:, 3] - anchors[:, 1]
        if view is None:
            bands = BAND_PER_WIDTH * (widths + 2 * COLUMN_STEP) if kind == "junction" else \
                np.maximum(heights, BAND_PER_WIDTH * widths)
            order = np.argsort(-widths, kind="stable")
        else:
            bands = self._pose_bands(kind, view, centre_x, centre_y)
            pole_widths = bands / BAND_PER_WIDTH
            excess = np.log(np.maximum(widths, COLUMN_STEP) / pole_widths)
            mismatch = np.where(excess > 0, excess, -NARROW_ANCHOR_WEIGHT * excess)
            keep = np.isfinite(bands) & (widths <= MAX_WIDTH_RATIO * pole_widths + 2 * COLUMN_STEP)
            order = np.flatnonzero(keep)[np.argsort(mismatch[keep], kind="stable")]
        windows = np.stack(window_at_junction(centre_x[order], centre_y[order], bands[order]), axis=1)
        return windows, anchors[order]

    def _pose_bands(self, kind: str, view: GroundView, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """A band's pixel size at each anchor from the camera's pose (NaN where no pole can stand): at the junction's
        height, or for a pink blob the geometric mean of the upper and the lower band's middle."""
        band_m = self.pole.band_height
        if kind == "junction":
            return band_m * view.pixels_per_metre(u, v, self.pole.divide_height)
        upper = view.pixels_per_metre(u, v, self.pole.divide_height + band_m / 2)
        lower = view.pixels_per_metre(u, v, self.pole.divide_height - band_m / 2)
        return band_m * np.sqrt(upper * lower)


def _interleaved(first: int, second: int) -> np.ndarray:
    """Indices that take turns between a list of ``first`` items and the ``second`` after it (0, first, 1, first + 1,
    ...), the longer list's rest at the end."""
    mine, theirs = np.arange(first), np.arange(second)
    return np.argsort(np.concatenate([mine + np.minimum(mine, second), theirs + np.minimum(theirs + 1, first)]))


def _blobs(mask: np.ndarray) -> np.ndarray:
    """(x, y, width, height, samples) rows, one per 8-connected blob of a grid mask with at least
    ``MIN_BLOB_SAMPLES``."""
    _, _, stats, _ = cv2.connectedComponentsWithStatsWithAlgorithm(mask, 8, cv2.CV_16U, cv2.CCL_SPAGHETTI)
    stats = stats[1:]
    return stats[stats[:, cv2.CC_STAT_AREA] >= MIN_BLOB_SAMPLES]
