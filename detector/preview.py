"""Contact sheets: a grid of images with their instance outlines and class names drawn, for a person to look at."""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from detector.datasets.model import Instance
from naoslam.atomic import write_bytes
from naoslam.landmarks import CLASSES

#: One BGR outline colour per class, in canonical order.
CLASS_BGR = [(230, 160, 60), (90, 175, 50), (50, 215, 240), (160, 70, 235), (120, 60, 200), (60, 120, 250)]


def draw_instances(image_bgr: np.ndarray, instances: list[Instance]) -> np.ndarray:
    """A copy of the image with each instance's polygon outlined and labelled with its class."""
    out = image_bgr.copy()
    h, w = out.shape[:2]
    thickness = max(1, round(w / 400))
    for instance in instances:
        colour = CLASS_BGR[CLASSES.index(instance.cls)]
        points = np.round(instance.pixels(w, h)).astype(np.int32)
        cv2.polylines(out, [points], True, colour, thickness, cv2.LINE_AA)
        x, y = points[:, 0].min(), max(points[:, 1].min() - 4, 12)
        cv2.putText(out, instance.cls, (int(x), int(y)), cv2.FONT_HERSHEY_SIMPLEX, 0.4 * thickness + 0.1, colour, thickness, cv2.LINE_AA)
    return out


def contact_sheet(tiles: list[tuple[np.ndarray, str]], path: str | Path, columns: int = 4, tile_width: int = 320) -> Path:
    """Write a PNG grid of (BGR image, caption) tiles, each scaled to ``tile_width``; returns the path."""
    if not tiles:
        raise ValueError("no images for the contact sheet")
    scaled = []
    for image, caption in tiles:
        tile = cv2.resize(image, (tile_width, round(image.shape[0] * tile_width / image.shape[1])), interpolation=cv2.INTER_AREA)
        cv2.rectangle(tile, (0, 0), (tile_width, 16), (0, 0, 0), -1)
        cv2.putText(tile, caption[:48], (4, 12), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (255, 255, 255), 1, cv2.LINE_AA)
        scaled.append(tile)
    tile_h = max(t.shape[0] for t in scaled)
    blank = np.zeros((tile_h, tile_width, 3), np.uint8)
    scaled = [cv2.copyMakeBorder(t, 0, tile_h - t.shape[0], 0, 0, cv2.BORDER_CONSTANT) for t in scaled]
    scaled += [blank] * (-len(scaled) % columns)
    rows = [np.hstack(scaled[i : i + columns]) for i in range(0, len(scaled), columns)]
    ok, encoded = cv2.imencode(".png", np.vstack(rows))
    return write_bytes(path, encoded.tobytes())
