"""What the runtime accepts as a camera frame: an HxWx3 BGR uint8 array (grey, BGRA and the Nao camera's own
YUV 4:2:2 are converted).

One check for every front end (the network and the colour filter), because the failure it stops is silent: a frame
in 0..1 floats, as many image libraries hand over, reaches the network 255 times too dark and finds no pole, and a
16-bit frame overflows the colour filter's lookup table.

An HxWx2 frame is read as YUYV (Y0 U Y1 V), the packed YUV 4:2:2 that the Nao's cameras deliver through V4L2
(``V4L2_PIX_FMT_YUYV``): a robot program passes the camera's buffer as ``buffer.reshape(height, width, 2)``. The
Nao's YUV is full-range BT.601 (JPEG's YCbCr, as B-Human's conversions read it); OpenCV's own YUYV conversion
assumes video range (16-235) and would stretch contrast and saturation, so the chroma is spread over each pixel
pair here and converted as YCrCb.
"""
from __future__ import annotations

import cv2
import numpy as np


def bgr_frame(frame: np.ndarray) -> np.ndarray:
    """``frame`` as HxWx3 BGR uint8; grey (HxW, HxWx1), YUYV (HxWx2) and BGRA are converted, anything else is
    refused."""
    frame = np.asarray(frame)
    if frame.size == 0 or frame.ndim not in (2, 3) or (frame.ndim == 3 and frame.shape[2] not in (1, 2, 3, 4)):
        raise ValueError(f"frame of shape {frame.shape} is empty or not an image - pass an HxWx3 BGR uint8 array")
    if frame.dtype != np.uint8:
        raise ValueError(f"frame of dtype {frame.dtype} - pass a uint8 frame (0-255) as the camera and cv2.imread "
                         "give it; convert a 0..1 float image with (frame * 255).round().astype(np.uint8)")
    if frame.ndim == 2 or frame.shape[2] == 1:
        return cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR)
    if frame.shape[2] == 2:
        return _bgr_from_yuyv(frame)
    if frame.shape[2] == 4:
        return cv2.cvtColor(frame, cv2.COLOR_BGRA2BGR)
    return frame


def _bgr_from_yuyv(frame: np.ndarray) -> np.ndarray:
    """A full-range YUYV frame (each pixel pair shares one U and one V, so the width is even) as BGR."""
    if frame.shape[1] % 2:
        raise ValueError(f"frame of shape {frame.shape}: an HxWx2 frame is read as the Nao camera's YUYV, whose "
                         "width is even - pass the camera's buffer as buffer.reshape(height, width, 2), or a BGR "
                         "frame")
    luma, chroma = frame[..., 0], frame[..., 1]
    ycrcb = np.empty(frame.shape[:2] + (3,), np.uint8)
    ycrcb[..., 0] = luma
    ycrcb[..., 1] = np.repeat(chroma[:, 1::2], 2, axis=1)  # V (Cr): every pixel pair's second byte
    ycrcb[..., 2] = np.repeat(chroma[:, 0::2], 2, axis=1)  # U (Cb): its first
    return cv2.cvtColor(ycrcb, cv2.COLOR_YCrCb2BGR)
