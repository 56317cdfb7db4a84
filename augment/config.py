"""The augmentation ranges (defaults: the 2024 thesis's Roboflow settings) and their validation."""
from __future__ import annotations

from dataclasses import dataclass, fields
from pathlib import Path

import yaml

#: Operation names, in the order they are applied when chosen: geometry, box-level, then colour.
OPERATIONS: tuple[str, ...] = ("rotate", "shear", "box_rotate", "box_brightness", "box_blur", "saturation", "brightness")

#: Augmented copies per training image, as the thesis made them.
THESIS_COPIES = 7


@dataclass(frozen=True)
class AugmentConfig:
    """Strength limits of each operation; a copy draws each chosen operation's strength uniformly within +-limit."""

    rotate_deg: float = 15.0
    shear_deg: float = 11.0
    saturation: float = 0.10
    brightness: float = 0.20
    box_rotate_deg: float = 5.0
    box_brightness: float = 0.15
    box_blur_px: float = 1.5
    #: Instances whose clipped polygon is smaller than this (px^2) are dropped from the copy.
    min_area_px: float = 20.0
    ops: tuple[str, ...] = OPERATIONS

    def __post_init__(self) -> None:
        limits = {"rotate_deg": 180.0, "shear_deg": 45.0, "saturation": 1.0, "brightness": 1.0, "box_rotate_deg": 45.0,
                  "box_brightness": 1.0, "box_blur_px": 20.0, "min_area_px": 1e6}
        for name, high in limits.items():
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ValueError(f"augmentation setting {name} = {value!r} is not a number (e.g. rotate_deg: 15)")
            if not 0.0 <= value <= high:
                raise ValueError(f"augmentation setting {name} = {value} is outside 0..{high:g}"
                                 " (limits are symmetric: give the magnitude, e.g. rotate_deg: 15 for +-15 deg)")
        unknown = [op for op in self.ops if op not in OPERATIONS]
        if unknown or not self.ops:
            raise ValueError(f"unknown or no operations {unknown or '(none)'}; choose from {', '.join(OPERATIONS)}")

    @classmethod
    def from_yaml(cls, path: str | Path, **overrides) -> "AugmentConfig":
        """Read settings from a YAML mapping (keys as the field names); ``overrides`` win."""
        path = Path(path)
        try:
            data = yaml.safe_load(path.read_text(encoding="utf-8")) or {}
        except (UnicodeDecodeError, yaml.YAMLError) as exc:
            raise ValueError(f"{path}: not a readable YAML file ({str(exc).splitlines()[0]}) - "
                             "write settings like `rotate_deg: 15`") from None
        if not isinstance(data, dict):
            raise ValueError(f"{path}: expected a mapping of settings, e.g. `rotate_deg: 15`")
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ValueError(f"{path}: unknown setting(s) {', '.join(unknown)}; known: {', '.join(sorted(known))}")
        data.update({k: v for k, v in overrides.items() if v is not None})
        if "ops" in data:
            data["ops"] = tuple(data["ops"]) if isinstance(data["ops"], (list, tuple)) else (data["ops"],)
        try:
            return cls(**data)
        except ValueError as exc:
            raise ValueError(f"{path}: {exc}") from None
