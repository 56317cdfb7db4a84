"""Bounding-box-level operations (albumentations has none): rotate, brighten or blur only what is inside each box.

They are albumentations ``DualTransform``s, so they compose with the whole-image operations in one pipeline.
Instance outlines travel as keypoints (pixel coordinates) with a parallel array ``vertex_instance`` naming the
instance of each vertex; keypoints must be set up with ``remove_invisible=False`` so rows stay aligned.
"""
from __future__ import annotations

import math
from typing import Any

import albumentations as A
import cv2
import numpy as np

from detector.datasets.polygons import polygon_to_mask

Box = tuple[int, int, int, int]


def instance_outlines(keypoints: np.ndarray, vertex_instance: np.ndarray) -> dict[int, np.ndarray]:
    """Instance id -> its outline (N, 2) in pixels."""
    return {int(i): keypoints[vertex_instance == i, :2] for i in np.unique(vertex_instance)}


def bounding_box(outline: np.ndarray, shape: tuple[int, int], pad: int = 0) -> Box | None:
    """Integer pixel box (x0, y0, x1, y1) around an outline, padded, clipped to the image; None if empty."""
    height, width = shape
    x0, y0 = np.floor(outline.min(axis=0)).astype(int) - pad
    x1, y1 = np.ceil(outline.max(axis=0)).astype(int) + pad
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, width), min(y1, height)
    return (int(x0), int(y0), int(x1), int(y1)) if x1 - x0 >= 2 and y1 - y0 >= 2 else None


class BoxTransform(A.DualTransform):
    """Base: draws one strength per instance box; subclasses say how to pad the box and what to do inside it."""

    def __init__(self, limit: float, p: float = 1.0):
        super().__init__(p=p)
        self.limit = limit

    def get_transform_init_args_names(self) -> tuple[str, ...]:
        return ("limit",)

    def box_padding(self, outline: np.ndarray, strength: float) -> int:
        return 0

    def sample_strength(self) -> float:
        return self.py_random.uniform(-self.limit, self.limit)

    def get_params_dependent_on_data(self, params: dict[str, Any], data: dict[str, Any]) -> dict[str, Any]:
        shape = params["shape"][:2]
        outlines = instance_outlines(np.asarray(data["keypoints"]), np.asarray(data["vertex_instance"]))
        boxes = []
        for instance, outline in outlines.items():
            strength = self.sample_strength()
            box = bounding_box(outline, shape, self.box_padding(outline, strength))
            if box is not None:
                boxes.append((instance, box, strength, outline))
        return {"boxes": boxes, "vertex_instance": np.asarray(data["vertex_instance"])}

    def apply_to_keypoints(self, keypoints: np.ndarray, **params: Any) -> np.ndarray:
        return keypoints


class BoxBrightness(BoxTransform):
    """Scale the brightness inside each instance's box by 1 +- ``limit`` (thesis: +-15 %)."""

    def apply(self, img: np.ndarray, boxes=(), **params: Any) -> np.ndarray:
        out = img.copy()
        for _, (x0, y0, x1, y1), strength, _ in boxes:
            out[y0:y1, x0:x1] = np.clip(out[y0:y1, x0:x1].astype(np.float32) * (1.0 + strength), 0, 255).astype(img.dtype)
        return out


class BoxBlur(BoxTransform):
    """Gaussian blur of up to ``limit`` px (sigma) inside each box, from the box's own pixels only (thesis: 1.5 px)."""

    def sample_strength(self) -> float:
        return self.py_random.uniform(0.0, self.limit)

    def apply(self, img: np.ndarray, boxes=(), **params: Any) -> np.ndarray:
        out = img.copy()
        for _, (x0, y0, x1, y1), sigma, _ in boxes:
            if sigma > 0.05:
                out[y0:y1, x0:x1] = cv2.GaussianBlur(img[y0:y1, x0:x1], (0, 0), sigma, borderType=cv2.BORDER_REFLECT_101)
        return out


class BoxRotate(BoxTransform):
    """Rotate each instance by +- ``limit`` degrees about its box centre (thesis: +-5 deg), outline with it.

    The box is padded so the turned object fits inside it; the object is lifted out, the hole it leaves is
    inpainted from the box's own pixels, and the turned object is put back: nothing from outside the box is
    smeared in and no hole is left. An instance whose padded box overlaps another instance's is left alone
    (turning it would cut into the other's label).
    """

    def box_padding(self, outline: np.ndarray, strength: float) -> int:
        width, height = np.ptp(outline, axis=0)
        angle = math.radians(abs(strength))
        return int(math.ceil(0.5 * height * math.sin(angle) + 0.5 * width * (1 - math.cos(angle)))) + 3

    def get_params_dependent_on_data(self, params: dict[str, Any], data: dict[str, Any]) -> dict[str, Any]:
        result = super().get_params_dependent_on_data(params, data)
        result["boxes"] = [b for b in result["boxes"] if not any(_overlap(b[1], o[1]) for o in result["boxes"] if o is not b)]
        result["matrices"] = {instance: _rotation_about(box, strength) for instance, box, strength, _ in result["boxes"]}
        return result

    def apply(self, img: np.ndarray, boxes=(), matrices=None, **params: Any) -> np.ndarray:
        out = img.copy()
        for instance, (x0, y0, x1, y1), _, outline in boxes:
            crop = img[y0:y1, x0:x1]
            local = matrices[instance].copy()
            local[:, 2] += local[:, :2] @ np.array([x0, y0]) - np.array([x0, y0])
            mask = polygon_to_mask(outline - np.array([x0, y0]), x1 - x0, y1 - y0).astype(np.uint8)
            background = cv2.inpaint(crop, cv2.dilate(mask, np.ones((5, 5), np.uint8)), 3, cv2.INPAINT_TELEA)
            size = (x1 - x0, y1 - y0)
            turned = cv2.warpAffine(crop, local, size, flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT_101)
            turned_mask = cv2.warpAffine(mask * 255, local, size, flags=cv2.INTER_LINEAR) > 127
            background[turned_mask] = turned[turned_mask]
            out[y0:y1, x0:x1] = background
        return out

    def apply_to_keypoints(self, keypoints: np.ndarray, matrices=None, vertex_instance=None, **params: Any) -> np.ndarray:
        out = keypoints.copy()
        for instance, matrix in (matrices or {}).items():
            rows = vertex_instance == instance
            # Outline points are continuous coordinates (pixel centres at +0.5); the matrix works on indices.
            xy = out[rows, :2] - 0.5
            out[rows, :2] = xy @ matrix[:, :2].T + matrix[:, 2] + 0.5
        return out


def _rotation_about(box: Box, degrees: float) -> np.ndarray:
    """2x3 matrix (pixel-index coordinates of the whole image) turning by ``degrees`` about the box centre."""
    x0, y0, x1, y1 = box
    return cv2.getRotationMatrix2D(((x0 + x1 - 1) / 2.0, (y0 + y1 - 1) / 2.0), degrees, 1.0)


def _overlap(a: Box, b: Box) -> bool:
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]
