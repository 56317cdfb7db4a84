"""Export a trained checkpoint to ONNX with Ultralytics, then stamp the naoslam metadata entry.

The checkpoint is copied to a scratch folder first: Ultralytics writes its export beside the weights, and a user's
files are never touched. The final model is moved into place atomically.
"""
from __future__ import annotations

import logging
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Any


from detector.outputs import check_output_file
from detector.model_files import write_metadata
from naoslam.perception.model_info import ModelInfo

#: Network input (height, width) for the Nao's 640x480 frames: no letterbox padding.
NAO_INPUT_HW = (480, 640)


def int8_path(model: Path) -> Path:
    """Where ``poles export --int8`` writes the INT8 copy of the FP32 ``model``: beside it, as ``<stem>-int8.onnx``."""
    return Path(model).with_name(f"{Path(model).stem}-int8.onnx")


def export_onnx(weights: Path, out: Path, input_hw: tuple[int, int] = NAO_INPUT_HW, force: bool = False,
                extra: dict[str, Any] | None = None, dynamic: bool = False) -> Path:
    """Export ``weights`` (an Ultralytics segmentation .pt) to ONNX; returns ``out``.

    ``input_hw`` is the full frame's input size, each side a multiple of the model's stride. ``dynamic`` lets the
    input height and width vary (multiples of the stride), so the front end can run the network on the band below
    the horizon alone (``LandmarkDetector``'s crop). The network is rewritten for the Nao's instruction set first
    (``export.atom_graph``: the same values from operators that compile and run fast at SSE4.1).
    """
    from ultralytics import YOLO  # deferred: `int8_path` and the names here stay light for every command

    from export.atom_graph import rewrite_for_atom

    weights, out = Path(weights), Path(out)
    if not weights.is_file():
        raise FileNotFoundError(f"{weights}: no such checkpoint - train one with `poles train`")
    check_output_file(out, force, (weights,))
    with tempfile.TemporaryDirectory(prefix="poles-export-") as scratch:
        copy = Path(scratch) / weights.name
        shutil.copyfile(weights, copy)
        model = YOLO(str(copy))
        if model.task != "segment":
            raise ValueError(f"{weights}: a {model.task} model, not a segmentation model - train a *-seg model")
        stride = int(max(model.model.stride))
        if any(side % stride for side in input_hw):
            raise ValueError(f"--imgsz {input_hw[0]} {input_hw[1]}: both sides must be multiples of the model's "
                             f"stride {stride}")
        rewrite_for_atom(model.model.model)
        with _quiet_ultralytics():  # nms=None: the raw outputs, decoded by naoslam (False warns of a missing head)
            exported = Path(model.export(format="onnx", imgsz=list(input_hw), simplify=True, dynamic=dynamic,
                                         nms=None, device="cpu", verbose=False))
        names = model.names
        info = ModelInfo(tuple(names[i] for i in sorted(names)), tuple(input_hw), stride,
                         _model_name(model), dict(extra or {}))
        write_metadata(exported, info, out)
    return out


@contextmanager
def _quiet_ultralytics():
    """Keep Ultralytics' export banner (paths in a scratch folder, netron links) off the terminal."""
    from ultralytics.utils import LOGGER

    level = LOGGER.level
    LOGGER.setLevel(logging.WARNING)
    try:
        yield
    finally:
        LOGGER.setLevel(level)


def _model_name(model) -> str:
    yaml_file = Path(str(getattr(model.model, "yaml", {}).get("yaml_file", "")))
    return yaml_file.stem or "yolov8-seg"


