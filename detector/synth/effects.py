"""What the Nao's camera does to a frame: colour temperature, exposure and contrast, motion blur, defocus, noise."""
from __future__ import annotations

import albumentations as A
import numpy as np


def camera_effects() -> A.Compose:
    """An albumentations pipeline of sensor and motion effects; labels are unaffected (no geometry changes)."""
    return A.Compose([
        A.PlanckianJitter(mode="blackbody", temperature_limit=(3500, 8000), p=0.7),
        A.RandomBrightnessContrast(brightness_limit=0.2, contrast_limit=0.25, p=0.7),
        A.RandomGamma(gamma_limit=(80, 125), p=0.4),
        A.OneOf([A.MotionBlur(blur_limit=(3, 9), p=1.0), A.GaussianBlur(sigma_limit=(0.3, 1.0), p=1.0)], p=0.35),
        A.ISONoise(color_shift=(0.01, 0.04), intensity=(0.05, 0.3), p=0.3),
        A.GaussNoise(std_range=(0.01, 0.04), p=0.7),
    ])


def apply_camera_effects(pipeline: A.Compose, image_rgb: np.ndarray, seed: int) -> np.ndarray:
    """Apply the pipeline to a uint8 RGB image, reproducibly for ``seed``."""
    pipeline.set_random_seed(seed)
    return pipeline(image=image_rgb)["image"]
