"""Fixed-size crops of a frame's candidate windows: the crop network's input, the same function on the robot and in
training.

A window (x0, y0, x1, y1, in frame pixels) is cut from the frame as the camera delivers it (BGR, or the YUYV buffer,
converted window by window), resized to the crop size (area averaging when it shrinks, bilinear when it grows) and
placed on a black canvas where it reaches outside the frame. Boxes move between frame and crop coordinates with
:func:`to_crop` and :func:`to_frame`, normalised to the crop's width and height.
"""
from __future__ import annotations

import cv2
import numpy as np

from naoslam.perception.frames import bgr_frame

Window = tuple[float, float, float, float]


def _is_yuyv(frame: np.ndarray) -> bool:
    return frame.ndim == 3 and frame.shape[2] == 2


def crop_window(frame: np.ndarray, window: Window, size_wh: tuple[int, int]) -> np.ndarray:
    """One window of a BGR or YUYV frame as a ``size_wh`` BGR uint8 crop (black outside the frame)."""
    width, height = size_wh
    frame_h, frame_w = frame.shape[:2]
    x0, y0, x1, y1 = window
    scale_x, scale_y = width / max(x1 - x0, 1e-6), height / max(y1 - y0, 1e-6)
    c0, r0 = max(int(np.floor(x0)), 0), max(int(np.floor(y0)), 0)
    c1, r1 = min(int(np.ceil(x1)), frame_w), min(int(np.ceil(y1)), frame_h)
    if _is_yuyv(frame):  # whole pixel pairs, so every pixel keeps its own chroma
        c0, c1 = c0 - c0 % 2, min(c1 + c1 % 2, frame_w)
    canvas = np.zeros((height, width, 3), np.uint8)
    if c1 <= c0 or r1 <= r0:
        return canvas
    # Where the part inside the frame lands on the canvas.
    d0, e0 = int(round((c0 - x0) * scale_x)), int(round((r0 - y0) * scale_y))
    d1, e1 = min(int(round((c1 - x0) * scale_x)), width), min(int(round((r1 - y0) * scale_y)), height)
    d0, e0 = min(max(d0, 0), width - 1), min(max(e0, 0), height - 1)
    d1, e1 = max(d1, d0 + 1), max(e1, e0 + 1)
    region = frame[r0:r1, c0:c1]
    if _is_yuyv(frame):
        region = bgr_frame(np.ascontiguousarray(region))
    shrinking = (c1 - c0) > 2 * (d1 - d0)
    canvas[e0:e1, d0:d1] = cv2.resize(region, (d1 - d0, e1 - e0),
                                      interpolation=cv2.INTER_AREA if shrinking else cv2.INTER_LINEAR)
    return canvas


def crop_batch(frame: np.ndarray, windows: list[Window], size_wh: tuple[int, int]) -> np.ndarray:
    """Every window as one (N, height, width, 3) BGR uint8 array."""
    out = np.empty((len(windows), size_wh[1], size_wh[0], 3), np.uint8)
    for i, window in enumerate(windows):
        out[i] = crop_window(frame, window, size_wh)
    return out


def to_crop(box: Window, window: Window) -> np.ndarray:
    """A frame box (x0, y0, x1, y1) in the window's normalised coordinates (0..1 inside it)."""
    x0, y0, x1, y1 = window
    scale = np.array([x1 - x0, y1 - y0, x1 - x0, y1 - y0])
    return (np.asarray(box, float) - [x0, y0, x0, y0]) / scale


def to_frame(boxes: np.ndarray, windows: np.ndarray) -> np.ndarray:
    """Normalised crop boxes (N, 4) back in frame pixels, each with its window (N, 4)."""
    windows = np.asarray(windows, float)
    size = np.concatenate([windows[:, 2:] - windows[:, :2]] * 2, axis=1)
    return boxes * size + np.concatenate([windows[:, :2]] * 2, axis=1)
