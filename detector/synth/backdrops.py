"""Real robot-camera frames without poles as backdrops: rendered poles composited so the result reads as one photo.

The ray-caster draws the objects (poles, look-alikes) over a real frame instead of the modelled room. Labels stay
exact because the masks come from the ray-caster; the frame only changes how the objects look: their light and
white balance follow the frame's (the colour its brightest surfaces show, not its mean colour: a green carpet is
content, not light), a back-lit frame darkens them and lowers their contrast, and their edges get the frame's
softness. Pixels more than ``FEATHER_REACH_PX`` from every object keep the frame's values (before the camera
effects that apply to the whole image).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import cv2
import numpy as np

from detector.datasets.io import IMAGE_SUFFIXES, decode_frame

#: Smallest backdrop accepted (a pole at range must still be resolvable).
MIN_WIDTH, MIN_HEIGHT = 160, 120
#: Backdrops narrower than this are upscaled to it: the detector runs on 640x480 frames.
RENDER_MIN_WIDTH = 640
#: Backdrops wider than this (a phone's or a DSLR's photographs) are downscaled to it: the Nao's largest frame. The
#: poles are drawn for a camera of the frame's own size either way; at full size a 4032x3024 photograph took 2.5 s a
#: frame, wrote 4032x3024 images that training shrinks to 640 anyway, and filled the backdrop cache with 1.2 GB.
RENDER_MAX_WIDTH = 1280
#: How far (px) the soft object edges reach into the frame.
FEATHER_REACH_PX = 3
#: Share of backdrop frames whose objects are back-lit (a window or a bright hall behind them), by default.
BACKLIGHT_SHARE = 0.2
#: The frame's cast is read from its brightest pixels: this top percentile of brightness, clipped pixels excluded.
WHITE_PATCH_PERCENTILE = 99.0
CLIPPED = 0.98


class BackdropError(ValueError):
    """A backdrop folder or file that cannot be used, with the fix in the message."""


@dataclass(frozen=True)
class Look:
    """How the objects must look to belong in one frame: light level, colour cast, back light, softness, paint.

    ``saturation`` < 1 mixes the modelled paint towards grey: real paint under room light is less vivid.
    """

    light_scale: float
    channel_gain: tuple[float, float, float]
    backlight_gain: float
    haze: float
    haze_rgb: tuple[float, float, float]
    blur_sigma: float
    saturation: float


def scan_backdrops(folder: Path) -> tuple[Path, ...]:
    """Every usable image in ``folder`` and its subfolders (sorted), or a ``BackdropError`` naming the first bad file.
    Files of other types (a README, notes) are ignored."""
    folder = Path(folder)
    if not folder.is_dir():
        raise BackdropError(f"--backgrounds {folder}: no such folder - point it at frames recorded without poles")
    paths = tuple(sorted(p for p in folder.rglob("*") if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES))
    if not paths:
        raise BackdropError(f"--backgrounds {folder}: no images ({', '.join(sorted(IMAGE_SUFFIXES))}) in it - "
                            "add robot-camera frames without poles")
    for path in paths:
        height, width = _decoded(path).shape[:2]
        if width < MIN_WIDTH or height < MIN_HEIGHT:
            raise BackdropError(f"{path}: {width}x{height} is too small for a backdrop (at least {MIN_WIDTH}x{MIN_HEIGHT}) "
                                "- remove it or use the camera's full-size frames")
    return paths


@lru_cache(maxsize=8)
def load_backdrop(path: Path) -> np.ndarray:
    """The frame as RGB float32 in 0..1, scaled (aspect kept) to between ``RENDER_MIN_WIDTH`` and
    ``RENDER_MAX_WIDTH`` wide."""
    image = _decoded(path)
    height, width = image.shape[:2]
    target = min(max(width, RENDER_MIN_WIDTH), RENDER_MAX_WIDTH)
    if target != width:
        image = cv2.resize(image, (target, round(height * target / width)),
                           interpolation=cv2.INTER_CUBIC if target > width else cv2.INTER_AREA)
    rgb = cv2.cvtColor(image, cv2.COLOR_BGR2RGB).astype(np.float32) / 255.0
    rgb.setflags(write=False)
    return rgb


def _decoded(path: Path) -> np.ndarray:
    try:
        return decode_frame(path)
    except ValueError as fault:
        raise BackdropError(f"{path}: {fault} - remove it from the backgrounds folder or re-save it") from None


def frame_cast(backdrop: np.ndarray) -> np.ndarray:
    """The frame's colour cast as RGB gains of mean 1: the mean colour of its brightest unclipped pixels (white patch).

    White field lines, walls and windows show the light and the camera's white balance; the frame's mean colour
    (grey world) would instead take a green carpet's colour for a green light and push blue paint towards green.
    """
    pixels = backdrop.reshape(-1, 3)
    pixels = pixels[pixels.max(axis=1) < CLIPPED]
    if len(pixels) == 0:
        return np.ones(3)
    brightness = pixels.mean(axis=1)
    brightest = pixels[brightness >= np.percentile(brightness, WHITE_PATCH_PERCENTILE)].mean(axis=0)
    return brightest / max(float(brightest.mean()), 1e-3)


@lru_cache(maxsize=256)
def backdrop_cast(path: Path) -> np.ndarray:
    """``frame_cast`` of the backdrop at ``path``, computed once per file (about 60 ms at 1280x960)."""
    cast = frame_cast(load_backdrop(path))
    cast.setflags(write=False)
    return cast


def sample_look(rng: np.random.Generator, backdrop: np.ndarray, cast: np.ndarray,
                backlight_share: float = BACKLIGHT_SHARE) -> Look:
    """The objects' look for this frame: light from its brightness, ``cast`` (``frame_cast``) for its white balance,
    back light with probability ``backlight_share``."""
    means = backdrop.reshape(-1, 3).mean(axis=0)
    luminance = float(means @ np.array([0.299, 0.587, 0.114]))
    light_scale = float(np.clip(luminance / 0.45, 0.45, 1.35) * rng.uniform(0.85, 1.15))
    gain = np.clip(cast, 0.75, 1.3) ** rng.uniform(0.3, 0.8)
    backlit = rng.random() < backlight_share
    return Look(light_scale=light_scale, channel_gain=tuple(float(g) for g in gain),
                backlight_gain=float(rng.uniform(0.25, 0.6)) if backlit else 1.0,
                haze=float(rng.uniform(0.1, 0.35)) if backlit else 0.0,
                haze_rgb=tuple(float(c) for c in means), blur_sigma=float(rng.uniform(0.35, 1.1)),
                saturation=float(rng.uniform(0.5, 1.0)))


def composite(backdrop: np.ndarray, objects_rgb: np.ndarray, coverage: np.ndarray, look: Look) -> np.ndarray:
    """The frame with the objects drawn in: ``objects_rgb`` where ``coverage`` (bool mask), in the frame's look.

    Returns a new float image; ``backdrop`` is not modified. Only pixels within ``FEATHER_REACH_PX`` of the
    coverage differ from the backdrop.
    """
    grey = objects_rgb.mean(axis=-1, keepdims=True)
    paint = grey + look.saturation * (objects_rgb - grey)
    lit = paint * (look.light_scale * look.backlight_gain) * np.asarray(look.channel_gain, np.float32)
    lit = (1.0 - look.haze) * lit + look.haze * np.asarray(look.haze_rgb, np.float32)
    alpha = coverage.astype(np.float32)
    if look.blur_sigma > 0:
        lit = cv2.GaussianBlur(np.where(coverage[..., None], lit, backdrop).astype(np.float32), (0, 0), look.blur_sigma)
        alpha = cv2.GaussianBlur(alpha, (2 * FEATHER_REACH_PX + 1,) * 2, look.blur_sigma)
    alpha = alpha[..., None]
    return np.clip(alpha * lit + (1.0 - alpha) * backdrop, 0.0, 1.0).astype(np.float32)
