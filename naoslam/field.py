"""The SPL field (9 x 6 m) and where the six pole landmarks stand on it."""
from __future__ import annotations

from dataclasses import dataclass

from naoslam.landmarks import CLASSES


@dataclass(frozen=True)
class FieldGeometry:
    """SPL field dimensions in metres (rules since 2020): origin at the centre, x towards the opponent goal."""

    length: float = 9.0
    width: float = 6.0
    border: float = 0.7
    line_width: float = 0.05
    centre_circle_radius: float = 0.75
    penalty_area_length: float = 1.65
    penalty_area_width: float = 4.0
    goal_area_length: float = 0.6
    goal_area_width: float = 2.2
    penalty_mark_distance: float = 1.3
    goal_width: float = 1.5
    goal_post_diameter: float = 0.1
    goal_height: float = 0.8


#: Gutmann's 3 x 2 m beacon layout (x in {-1.5, 0, 1.5} m, y = +-1 m) scaled to the 9 x 6 m field.
GUTMANN_LANDMARKS: dict[str, tuple[float, float]] = dict(zip(
    CLASSES,
    [(-4.675, 3.175), (0.0, 3.175), (4.675, 3.175), (-4.675, -3.175), (0.0, -3.175), (4.675, -3.175)],
))
