"""Contact sheets: a grid of images with their instance outlines and class names drawn, for a person to look at."""
from __future__ import annotations

import re
from pathlib import Path

import cv2
import numpy as np

from detector.datasets.model import Instance
from detector.atomic import write_bytes
from naoslam.landmarks import CLASSES

#: One BGR outline colour per class, in canonical order.
CLASS_BGR = [(230, 160, 60), (90, 175, 50), (50, 215, 240), (160, 70, 235), (120, 60, 200), (60, 120, 250)]


#: Text on frames and sheets: OpenCV's built-in Hershey font (nothing to download); captions' scale and line height.
FONT = cv2.FONT_HERSHEY_SIMPLEX
CAPTION_SCALE, CAPTION_LINE_PX = 0.4, 13


def draw_label(image_bgr: np.ndarray, text: str, origin: tuple[int, int], colour, scale: float = 0.45,
               thickness: int = 1) -> None:
    """Write ``text`` in ``colour`` at ``origin`` (its baseline's left end) with a dark edge, readable on any floor,
    wall or pole; moved left or down as far as needed to stay whole inside the image (a pole at the border)."""
    (text_w, text_h), _ = cv2.getTextSize(text, FONT, scale, thickness + 2)
    x = max(0, min(origin[0], image_bgr.shape[1] - text_w - 1))
    y = max(origin[1], text_h + 1)
    for ink, width in (((0, 0, 0), thickness + 2), (colour, thickness)):
        cv2.putText(image_bgr, text, (x, y), FONT, scale, ink, width, cv2.LINE_AA)


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
        draw_label(out, instance.cls, (int(x), int(y)), colour, 0.4 * thickness + 0.1, thickness)
    return out


def wrap_caption(caption: str, width_px: int) -> list[str]:
    """The caption broken after spaces and '+' into lines no wider than ``width_px`` (a word wider than that keeps
    a line of its own)."""
    lines = [""]
    for piece in re.findall(r"[^ +]+[ +]*|[ +]+", caption):
        trial = lines[-1] + piece
        if lines[-1] and cv2.getTextSize(trial.rstrip(), FONT, CAPTION_SCALE, 1)[0][0] > width_px:
            lines.append(piece)
        else:
            lines[-1] = trial
    return [line.rstrip() for line in lines if line.strip()]


def contact_sheet(tiles: list[tuple[np.ndarray, str]], path: str | Path, columns: int = 4, tile_width: int = 320) -> Path:
    """Write a PNG grid of (BGR image, caption) tiles, each scaled to ``tile_width`` under its caption (wrapped to
    the tile's width, never cut); returns the path."""
    if not tiles:
        raise ValueError("no images for the contact sheet")
    captions = [wrap_caption(caption, tile_width - 8) for _, caption in tiles]
    header_h = 4 + CAPTION_LINE_PX * max(1, *map(len, captions))
    scaled = []
    for (image, _), lines in zip(tiles, captions):
        tile = cv2.resize(image, (tile_width, round(image.shape[0] * tile_width / image.shape[1])), interpolation=cv2.INTER_AREA)
        header = np.zeros((header_h, tile_width, 3), np.uint8)
        for number, line in enumerate(lines, start=1):
            cv2.putText(header, line, (4, CAPTION_LINE_PX * number - 1), FONT, CAPTION_SCALE, (255, 255, 255),
                        1, cv2.LINE_AA)
        scaled.append(np.vstack([header, tile]))
    tile_h = max(t.shape[0] for t in scaled)
    blank = np.zeros((tile_h, tile_width, 3), np.uint8)
    scaled = [cv2.copyMakeBorder(t, 0, tile_h - t.shape[0], 0, 0, cv2.BORDER_CONSTANT) for t in scaled]
    scaled += [blank] * (-len(scaled) % columns)
    rows = [np.hstack(scaled[i : i + columns]) for i in range(0, len(scaled), columns)]
    ok, encoded = cv2.imencode(".png", np.vstack(rows))
    return write_bytes(path, encoded.tobytes())
