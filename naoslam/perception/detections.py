"""One pole detection, whoever found it: the ONNX front end, the robot's two-stage front end, the colour filter, or
Ultralytics on the training side.

Every front end returns ``Detection`` objects, and everything downstream (the measurement model, evaluation as the
thesis counted, the export's agreement check, the overlays) reads them. The adapters that build one from what a
finder has in hand live here, as class methods: ``from_mask`` (a full-frame mask: the colour filter's bands, an
Ultralytics mask), ``from_box`` (the robot front end, which finds boxes and no mask) and ``from_ultralytics`` (an Ultralytics ``Results``, read by duck typing: naoslam never imports
Ultralytics).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from naoslam.ground import PoleExtent
from naoslam.landmarks import CLASSES


@dataclass(frozen=True)
class RotatedBox:
    """Minimum-area rectangle around a mask: centre (px), width/height (px) and tilt of the height side from vertical."""

    cx: float
    cy: float
    width: float
    height: float
    angle_deg: float

    @classmethod
    def of_points(cls, points: np.ndarray) -> "RotatedBox":
        """Fit ``cv2.minAreaRect`` to (N, 2) points; "height" is the side closer to the image vertical."""
        (cx, cy), _, _ = rect = cv2.minAreaRect(points.astype(np.float32))
        corners = cv2.boxPoints(rect)
        side_a, side_b = corners[1] - corners[0], corners[2] - corners[1]
        upright, across = (side_a, side_b) if abs(side_a[1]) >= abs(side_b[1]) else (side_b, side_a)
        if upright[1] > 0:
            upright = -upright
        angle = float(np.degrees(np.arctan2(upright[0], -upright[1])))
        return cls(float(cx), float(cy), float(np.hypot(*across)), float(np.hypot(*upright)), angle)


def rotated_box_of_mask(mask: np.ndarray, origin: tuple[int, int] = (0, 0)) -> RotatedBox | None:
    """Minimum-area rectangle around all of a mask's outlines (None for an empty mask), in frame pixels."""
    contours, _ = cv2.findContours(np.ascontiguousarray(mask, dtype=np.uint8), cv2.RETR_EXTERNAL,
                                   cv2.CHAIN_APPROX_NONE)
    if not contours:
        return None
    return RotatedBox.of_points(np.concatenate(contours).reshape(-1, 2) + origin)


def mask_centre_column(mask: np.ndarray, origin: tuple[int, int] = (0, 0)) -> float:
    """Mean column of a mask's pixels as a continuous image coordinate (pixel centres at index + 0.5)."""
    return float(np.nonzero(mask)[1].mean() + origin[0] + 0.5)


@dataclass(frozen=True)
class Detection:
    """One pole: class, confidence, box (x1, y1, x2, y2 in frame pixels), its mask cropped to ``mask_origin``, the
    rotated box around the mask and the mask's mean column. The colour filter also gives ``band_centres`` (the upper
    and the lower band's centre, x and y): its range comes from their distance, its place from their midpoint. A
    ``box_only`` detection has no mask: its rotated box is the upright box, its column the box's middle."""

    class_id: int
    name: str
    confidence: float
    box: tuple[float, float, float, float]
    mask: np.ndarray
    mask_origin: tuple[int, int]
    rotated_box: RotatedBox | None
    centre_column: float
    band_centres: tuple[tuple[float, float], tuple[float, float]] | None = None
    box_only: bool = False

    @property
    def extent(self) -> PoleExtent | None:
        """The pole's top and foot points: from its mask, or from its box when it has no mask (None: empty mask)."""
        return PoleExtent.of_box(self.box) if self.box_only else PoleExtent.of_mask(self.mask, self.mask_origin)

    def full_mask(self, frame_shape: tuple[int, ...]) -> np.ndarray:
        """The mask as a boolean array the size of the frame (height, width); a box-only detection's box, filled."""
        out = np.zeros(frame_shape[:2], dtype=bool)
        if self.box_only:
            x0, y0, x1, y1 = (int(round(v)) for v in self.box)
            out[max(y0, 0):max(y1, 0), max(x0, 0):max(x1, 0)] = True
            return out
        x0, y0 = self.mask_origin
        h, w = self.mask.shape
        out[y0:y0 + h, x0:x0 + w] = self.mask
        return out

    def mask_iou(self, other: "Detection") -> float:
        """Intersection over union of this detection's mask and ``other``'s (0 when both are empty)."""
        (ax, ay), (bx, by) = self.mask_origin, other.mask_origin
        x0, y0 = min(ax, bx), min(ay, by)
        x1 = max(ax + self.mask.shape[1], bx + other.mask.shape[1])
        y1 = max(ay + self.mask.shape[0], by + other.mask.shape[0])
        a, b = np.zeros((y1 - y0, x1 - x0), bool), np.zeros((y1 - y0, x1 - x0), bool)
        a[ay - y0:ay - y0 + self.mask.shape[0], ax - x0:ax - x0 + self.mask.shape[1]] = self.mask
        b[by - y0:by - y0 + other.mask.shape[0], bx - x0:bx - x0 + other.mask.shape[1]] = other.mask
        union = int((a | b).sum())
        return float((a & b).sum() / union) if union else 0.0

    @property
    def divide_centre(self) -> tuple[float, float] | None:
        """The centre of the line between the two bands (the band centres' midpoint), where the colour filter gives
        them."""
        if self.band_centres is None:
            return None
        (x0, y0), (x1, y1) = self.band_centres
        return (x0 + x1) / 2, (y0 + y1) / 2

    @property
    def band_distance_px(self) -> float | None:
        """Pixel length between the two band centres, the colour filter's range measure, where it gives them."""
        return math.dist(*self.band_centres) if self.band_centres is not None else None

    @classmethod
    def from_mask(cls, name: str, confidence: float, mask: np.ndarray, class_id: int | None = None,
                  box: tuple[float, float, float, float] | None = None, centre_column: float | None = None,
                  band_centres: tuple[tuple[float, float], tuple[float, float]] | None = None) -> "Detection":
        """A detection from a full-frame boolean mask, cropped to the mask's extent. ``class_id`` defaults to the
        landmark's place in ``CLASSES``, ``box`` to the mask's extent, ``centre_column`` to the mask's mean column
        (the box's middle for an empty mask)."""
        rows, columns = np.nonzero(mask)
        if len(rows):
            r0, r1, c0, c1 = int(rows.min()), int(rows.max()) + 1, int(columns.min()), int(columns.max()) + 1
        else:
            r0 = r1 = c0 = c1 = 0
        crop, origin = np.ascontiguousarray(mask[r0:r1, c0:c1], dtype=bool), (c0, r0)
        box = tuple(float(v) for v in box) if box is not None else (float(c0), float(r0), float(c1), float(r1))
        if centre_column is None:
            centre_column = mask_centre_column(crop, origin) if len(rows) else (box[0] + box[2]) / 2
        class_id = CLASSES.index(name) if class_id is None else class_id
        return cls(class_id, name, float(confidence), box, crop, origin,
                   rotated_box_of_mask(crop, origin), float(centre_column), band_centres)

    @classmethod
    def from_box(cls, name: str, confidence: float, box: tuple[float, float, float, float],
                 class_id: int | None = None) -> "Detection":
        """A detection of an upright pole's box (x0, y0, x1, y1 in frame pixels) with no mask."""
        x0, y0, x1, y1 = (float(v) for v in box)
        upright = RotatedBox((x0 + x1) / 2, (y0 + y1) / 2, x1 - x0, y1 - y0, 0.0)
        return cls(CLASSES.index(name) if class_id is None else class_id, name, float(confidence), (x0, y0, x1, y1),
                   np.zeros((0, 0), bool), (int(x0), int(y0)), upright, (x0 + x1) / 2, box_only=True)

    @classmethod
    def from_ultralytics(cls, result, frame_shape: tuple[int, ...]) -> list["Detection"]:
        """The detections of one Ultralytics segmentation ``Results`` (predicted with ``retina_masks=True``, so its
        masks have the frame's size), best first as Ultralytics orders them."""
        boxes = result.boxes
        if result.masks is None or not len(boxes):
            return []
        masks = result.masks.data.cpu().numpy() > 0.5
        names = result.names
        return [cls.from_mask(names[int(c)], float(s), mask.reshape(frame_shape[:2]), class_id=int(c), box=tuple(b))
                for c, s, b, mask in zip(boxes.cls.cpu().numpy(), boxes.conf.cpu().numpy(), boxes.xyxy.cpu().numpy(),
                                         masks)]
