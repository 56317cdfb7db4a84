"""One augmented copy: a random subset of the enabled operations, composed in one albumentations pipeline."""
from __future__ import annotations

from dataclasses import dataclass

import albumentations as A
import cv2
import numpy as np

from augment.box_ops import BoxBlur, BoxBrightness, BoxRotate
from augment.config import OPERATIONS, AugmentConfig
from detector.datasets.model import Instance
from detector.datasets.polygons import clip_polygon, polygon_area


def operation(name: str, config: AugmentConfig) -> A.BasicTransform:
    """The albumentations transform for one operation at the configured strength (always applied when chosen)."""
    black = {"border_mode": cv2.BORDER_CONSTANT, "fill": 0, "p": 1.0}
    s, b = config.saturation, config.brightness
    return {
        "rotate": lambda: A.Affine(rotate=(-config.rotate_deg, config.rotate_deg), **black),
        "shear": lambda: A.Affine(shear={"x": (-config.shear_deg, config.shear_deg), "y": (-config.shear_deg, config.shear_deg)}, **black),
        "saturation": lambda: A.ColorJitter(brightness=0, contrast=0, saturation=(1 - s, 1 + s), hue=0, p=1.0),
        "brightness": lambda: A.ColorJitter(brightness=(1 - b, 1 + b), contrast=0, saturation=0, hue=0, p=1.0),
        "box_rotate": lambda: BoxRotate(config.box_rotate_deg),
        "box_brightness": lambda: BoxBrightness(config.box_brightness),
        "box_blur": lambda: BoxBlur(config.box_blur_px),
    }[name]()


def choose_operations(rng: np.random.Generator, config: AugmentConfig) -> list[str]:
    """A random non-empty subset of the enabled operations, in the canonical order."""
    enabled = [op for op in OPERATIONS if op in config.ops]
    chosen = set(rng.choice(enabled, size=int(rng.integers(1, len(enabled) + 1)), replace=False))
    return [op for op in enabled if op in chosen]


@dataclass
class AugmentedCopy:
    """An augmented image with its surviving instances and how many were dropped."""

    image: np.ndarray
    instances: list[Instance]
    operations: list[str]
    dropped: int


def augment_copy(image: np.ndarray, instances: list[Instance], operations: list[str], config: AugmentConfig,
                 seed: int) -> AugmentedCopy:
    """Apply ``operations`` to an RGB/BGR uint8 image; outlines move with the same matrices, then are clipped."""
    height, width = image.shape[:2]
    size = np.array([width, height], np.float64)
    outlines = [i.pixels(width, height) for i in instances]
    keypoints = np.concatenate(outlines) if outlines else np.zeros((0, 2))
    vertex_instance = np.concatenate([np.full(len(o), k) for k, o in enumerate(outlines)]) if outlines else np.zeros(0, int)
    transforms = [operation(op, config) for op in operations]
    if any(isinstance(t, A.DualTransform) for t in transforms):
        pipeline = A.Compose(transforms, keypoint_params=A.KeypointParams(format="xy", remove_invisible=False), seed=seed)
        result = pipeline(image=image, keypoints=keypoints, vertex_instance=vertex_instance)
    else:  # colour only: outlines stay where they are
        result = A.Compose(transforms, seed=seed)(image=image) | {"keypoints": keypoints}
    moved = np.asarray(result["keypoints"], np.float64).reshape(-1, 2)
    kept, dropped = [], 0
    for k, instance in enumerate(instances):
        outline = clip_polygon(moved[vertex_instance == k], 0.0, 0.0, float(width), float(height))
        if len(outline) < 3 or polygon_area(outline) < config.min_area_px:
            dropped += 1
            continue
        kept.append(Instance(instance.cls, outline / size))
    return AugmentedCopy(result["image"], kept, operations, dropped)
