"""What an exported pole model is: class names, input size and optional calibration, read from ONNX metadata.

``poles export`` writes one metadata entry, ``naoslam``, holding JSON; models exported by Ultralytics alone are read
from Ultralytics' own entries (``names``, ``imgsz``, ``stride``).
"""
from __future__ import annotations

import ast
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

#: Key of the JSON metadata entry written by ``poles export``.
METADATA_KEY = "naoslam"


@dataclass(frozen=True)
class ModelInfo:
    """Class names, network input size (height, width), stride and extra entries (e.g. calibration)."""

    classes: tuple[str, ...]
    input_hw: tuple[int, int]
    stride: int = 32
    model: str = ""
    extra: dict[str, Any] = field(default_factory=dict)

    def to_json(self) -> str:
        return json.dumps({"classes": list(self.classes), "input_hw": list(self.input_hw), "stride": self.stride,
                           "model": self.model, **self.extra}, sort_keys=True)

    @classmethod
    def from_metadata(cls, metadata: dict[str, str], source: Path | str) -> "ModelInfo":
        """Read from an ONNX model's metadata map; ``source`` names the file in errors."""
        if METADATA_KEY in metadata:
            data = json.loads(metadata[METADATA_KEY])
            known = {"classes", "input_hw", "stride", "model"}
            return cls(tuple(data["classes"]), tuple(data["input_hw"]), int(data.get("stride", 32)),
                       data.get("model", ""), {k: v for k, v in data.items() if k not in known})
        if "names" in metadata and "imgsz" in metadata:
            names = ast.literal_eval(metadata["names"])
            classes = tuple(names[i] for i in sorted(names)) if isinstance(names, dict) else tuple(names)
            return cls(classes, tuple(ast.literal_eval(metadata["imgsz"])), int(metadata.get("stride", 32)))
        raise ValueError(f"{source}: the ONNX model has no class names in its metadata - export it with "
                         "`poles export` (or Ultralytics' export) rather than a bare torch.onnx.export")
