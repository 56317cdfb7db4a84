"""What the runtime accepts as a camera frame: an HxWx3 BGR uint8 array (grey and BGRA are converted).

One check for every front end (the network and the colour filter), because the failure it stops is silent: a frame
in 0..1 floats, as many image libraries hand over, reaches the network 255 times too dark and finds no pole, and a
16-bit frame overflows the colour filter's lookup table.
"""
from __future__ import annotations

import cv2
import numpy as np


def bgr_frame(frame: np.ndarray) -> np.ndarray:
    """``frame`` as HxWx3 BGR uint8; grey (HxW, HxWx1) and BGRA are converted, anything else is refused."""
    frame = np.asarray(frame)
    if frame.size == 0 or frame.ndim not in (2, 3) or (frame.ndim == 3 and frame.shape[2] not in (1, 3, 4)):
        raise ValueError(f"frame of shape {frame.shape} is empty or not an image - pass an HxWx3 BGR uint8 array")
    if frame.dtype != np.uint8:
        raise ValueError(f"frame of dtype {frame.dtype} - pass a uint8 frame (0-255) as the camera and cv2.imread "
                         "give it; convert a 0..1 float image with (frame * 255).round().astype(np.uint8)")
    if frame.ndim == 2 or frame.shape[2] == 1:
        return cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR)
    if frame.shape[2] == 4:
        return cv2.cvtColor(frame, cv2.COLOR_BGRA2BGR)
    return frame
