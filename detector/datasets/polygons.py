"""Polygon <-> mask conversion for instance labels (pixel centres at index + 0.5)."""
from __future__ import annotations

import cv2
import numpy as np

_SUBPIXEL_BITS = 4


def polygon_area(polygon: np.ndarray) -> float:
    """Absolute shoelace area of a polygon (N, 2)."""
    x, y = polygon[:, 0], polygon[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


def polygon_to_mask(polygon_px: np.ndarray, width: int, height: int) -> np.ndarray:
    """Rasterise a pixel-coordinate polygon to a boolean mask (every pixel whose centre the outline reaches)."""
    mask = np.zeros((height, width), np.uint8)
    if len(polygon_px) >= 3:
        pts = np.round((np.asarray(polygon_px, np.float64) - 0.5) * (1 << _SUBPIXEL_BITS)).astype(np.int32)
        cv2.fillPoly(mask, [pts], 1, lineType=cv2.LINE_8, shift=_SUBPIXEL_BITS)
    return mask.astype(bool)


def merge_polygons(polygons: list[np.ndarray]) -> np.ndarray:
    """Join several outlines of one instance into one polygon with zero-width bridges between nearest points.

    This is how a one-polygon-per-line label format stores an instance split in parts (by an occluder).
    """
    merged = np.asarray(polygons[0], np.float64)
    for part in polygons[1:]:
        part = np.asarray(part, np.float64)
        gaps = np.linalg.norm(merged[:, None, :] - part[None, :, :], axis=-1)
        i, j = np.unravel_index(int(np.argmin(gaps)), gaps.shape)
        merged = np.concatenate([merged[: i + 1], np.roll(part, -j, axis=0), part[j : j + 1], merged[i:]])
    return merged


def mask_to_polygon(mask: np.ndarray, epsilon_px: float = 0.5, min_area_px: float = 2.0) -> np.ndarray | None:
    """Outline of a boolean mask as one pixel-coordinate polygon (parts joined), or None for an empty mask.

    ``epsilon_px`` is the Douglas-Peucker tolerance: the outline stays within that distance of the mask edge.
    """
    contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    parts = []
    for contour in sorted(contours, key=cv2.contourArea, reverse=True):
        if cv2.contourArea(contour) < min_area_px:  # specks and one-pixel-wide slivers have no polygon
            continue
        simplified = cv2.approxPolyDP(contour, epsilon_px, closed=True).reshape(-1, 2).astype(np.float64)
        if len(simplified) < 3:
            simplified = contour.reshape(-1, 2).astype(np.float64)
        if len(simplified) >= 3:
            parts.append(simplified + 0.5)
    return merge_polygons(parts) if parts else None



def clip_polygon(polygon: np.ndarray, x0: float, y0: float, x1: float, y1: float) -> np.ndarray:
    """Sutherland-Hodgman clip of a polygon (N, 2) to the rectangle [x0, x1] x [y0, y1] (may return < 3 points)."""
    points = np.asarray(polygon, np.float64)
    for axis, bound, keep_below in ((0, x0, False), (0, x1, True), (1, y0, False), (1, y1, True)):
        if len(points) == 0:
            break
        inside = points[:, axis] <= bound if keep_below else points[:, axis] >= bound
        previous, previous_inside = points[-1], inside[-1]
        kept = []
        for point, point_inside in zip(points, inside):
            if point_inside != previous_inside:
                t = (bound - previous[axis]) / (point[axis] - previous[axis])
                kept.append(previous + t * (point - previous))
            if point_inside:
                kept.append(point)
            previous, previous_inside = point, point_inside
        points = np.array(kept).reshape(-1, 2)
    return points
