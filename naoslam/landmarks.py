"""The six coloured pole landmarks: class codes and the cylinder's dimensions."""
from __future__ import annotations

from dataclasses import dataclass

#: Canonical class order. A code names the two coloured bands top to bottom (``bp`` = blue over pink).
CLASSES: tuple[str, ...] = ("bp", "gp", "yp", "pb", "pg", "py")


@dataclass(frozen=True)
class PoleGeometry:
    """Dimensions of a landmark cylinder in metres.

    Defaults: the 2018 thesis measured 19.7-21.9 cm for both coloured bands together (so about 10.5 cm each);
    the white base is about as tall as both bands together (the real-poles annotations); the diameter of 9 cm is
    what the 2024 thesis's width and height power laws imply at 1-2 m (height about 0.42 m, width 8-10 cm with
    a 56.3 deg, 640 px camera).
    """

    diameter: float = 0.09
    band_height: float = 0.105
    base_height: float = 0.21

    @property
    def radius(self) -> float:
        return self.diameter / 2.0

    @property
    def height(self) -> float:
        """Total height: white base plus both coloured bands."""
        return self.base_height + 2.0 * self.band_height

    @property
    def divide_height(self) -> float:
        """Height above the ground of the line between the two coloured bands."""
        return self.base_height + self.band_height
