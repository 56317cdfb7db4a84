"""Fixed-size crops of a frame's candidate windows: the crop network's input, the same function on the robot and in
training.

A window (x0, y0, x1, y1, in frame pixels) is sampled once per crop pixel, bilinear at the pixel's centre, black where
the window reaches outside the frame. All windows of a frame are cut in one ``cv2.remap``, so a crop costs what the
crop holds, not what the window spans: a near pole's 300x900-pixel window (or a pink wall's) costs what a far pole's
does. (Area averaging every pixel of each window cost up to 16 ms a cluttered 1280x960 frame at the Atom's
instruction set; four samples per crop pixel, averaged, 1.2 ms for 24 windows and no better detections than one,
0.3 ms: docs/robot-model.md.) A YUYV
buffer (the Nao camera's) is sampled as it is: the luma at each sample, the pair's chroma from the half-width chroma
planes, converted as full-range BT.601 (``naoslam.perception.frames``) at the crops' size, never at the frame's.
Boxes move between frame and crop coordinates with :func:`to_crop` and :func:`to_frame`, normalised to the crop's
width and height.
"""
from __future__ import annotations

import cv2
import numpy as np

Window = tuple[float, float, float, float]


def _is_yuyv(frame: np.ndarray) -> bool:
    return frame.ndim == 3 and frame.shape[2] == 2


def sample_maps(windows: np.ndarray, size_wh: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """``cv2.remap``'s maps (x, y; float32, N * H rows of W) of every window's crop pixels, window after window: each
    at the centre of its cell, in OpenCV's pixel coordinates (a pixel's centre at its index)."""
    width, height = size_wh
    windows = np.asarray(windows, np.float64).reshape(-1, 4)
    cells_x = (np.arange(width) + 0.5) / width
    cells_y = (np.arange(height) + 0.5) / height
    xs = windows[:, 0, None] + cells_x[None] * (windows[:, 2] - windows[:, 0])[:, None] - 0.5  # (N, 2W)
    ys = windows[:, 1, None] + cells_y[None] * (windows[:, 3] - windows[:, 1])[:, None] - 0.5  # (N, 2H)
    map_x = np.broadcast_to(xs[:, None, :], (len(windows), height, width)).reshape(-1, width)
    map_y = np.broadcast_to(ys[:, :, None], (len(windows), height, width)).reshape(-1, width)
    return map_x.astype(np.float32), map_y.astype(np.float32)


def _sampled(frame: np.ndarray, map_x: np.ndarray, map_y: np.ndarray) -> np.ndarray:
    """The frame's BGR samples at the maps (black outside the frame)."""
    def remap(plane: np.ndarray, xs: np.ndarray, outside: int = 0) -> np.ndarray:
        return cv2.remap(plane, xs, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=outside)

    if not _is_yuyv(frame):
        return remap(frame, map_x)
    luma = remap(np.ascontiguousarray(frame[..., 0]), map_x)
    chroma_x = (map_x - 0.5) / 2  # a pixel pair's chroma sits between its two pixels
    # Outside the frame the chroma is neutral (128), so black stays black once converted.
    v = remap(np.ascontiguousarray(frame[:, 1::2, 1]), chroma_x, 128)
    u = remap(np.ascontiguousarray(frame[:, 0::2, 1]), chroma_x, 128)
    return cv2.cvtColor(cv2.merge([luma, v, u]), cv2.COLOR_YCrCb2BGR)


def crop_batch(frame: np.ndarray, windows, size_wh: tuple[int, int]) -> np.ndarray:
    """Every window of a BGR or YUYV frame as one (N, height, width, 3) BGR uint8 array."""
    width, height = size_wh
    windows = np.asarray(windows, np.float64).reshape(-1, 4)
    if not len(windows):
        return np.zeros((0, height, width, 3), np.uint8)
    return _sampled(frame, *sample_maps(windows, size_wh)).reshape(len(windows), height, width, 3)


def crop_window(frame: np.ndarray, window: Window, size_wh: tuple[int, int]) -> np.ndarray:
    """One window of a BGR or YUYV frame as a ``size_wh`` BGR uint8 crop (black outside the frame)."""
    return crop_batch(frame, [window], size_wh)[0]


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
