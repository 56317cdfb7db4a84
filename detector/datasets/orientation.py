"""Images stored turned or mirrored: the EXIF orientation tag that phone photos carry.

OpenCV applies the tag when it decodes a JPEG, PNG or WebP, and Ultralytics reads with OpenCV, so every command
here sees such an image upright. Its outlines are right only if they were drawn on the upright image too (Roboflow's
Auto-Orient preprocessing makes that so); a COCO file that declares the stored size was drawn on the stored pixels.
"""
from __future__ import annotations

import io
from pathlib import Path

from PIL import Image

EXIF_ORIENTATION_TAG = 0x0112
UPRIGHT = 1
#: Tag values whose transform swaps width and height: a quarter turn, mirrored or not.
QUARTER_TURNS = frozenset({5, 6, 7, 8})


def exif_orientation(image: Image.Image) -> int:
    """The image's EXIF orientation (1 stored upright, 2-8 mirrored and/or turned); 1 when absent or invalid."""
    value = image.getexif().get(EXIF_ORIENTATION_TAG, UPRIGHT)
    return value if value in range(1, 9) else UPRIGHT


def encoded_orientation(data: bytes) -> int:
    """``exif_orientation`` of an encoded image; 1 when Pillow cannot read its header."""
    try:
        with Image.open(io.BytesIO(data)) as image:
            return exif_orientation(image)
    except (OSError, ValueError):
        return UPRIGHT


def stored_and_upright_size(path: Path) -> tuple[tuple[int, int], tuple[int, int], int]:
    """(width, height) as stored, (width, height) as every reader here decodes it, and the orientation tag.
    Raises ``OSError`` or ``ValueError`` when the file is not an image Pillow can open."""
    with Image.open(path) as image:
        stored, orientation = image.size, exif_orientation(image)
    upright = stored[::-1] if orientation in QUARTER_TURNS else stored
    return stored, upright, orientation
