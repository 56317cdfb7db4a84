"""Export a trained checkpoint to ONNX with Ultralytics, then stamp the naoslam metadata entry.

The checkpoint is copied to a scratch folder first: Ultralytics writes its export beside the weights, and a user's
files are never touched. The final model is moved into place atomically.
"""
from __future__ import annotations

import logging
import shutil
import tempfile
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path
from typing import Any

import onnx

from detector.datasets.io import check_output_file
from naoslam.atomic import atomic_path
from naoslam.model_info import METADATA_KEY, ModelInfo

#: Network input (height, width) for the Nao's 640x480 frames: no letterbox padding.
NAO_INPUT_HW = (480, 640)


def int8_path(model: Path) -> Path:
    """Where ``poles export --int8`` writes the INT8 copy of the FP32 ``model``: beside it, as ``<stem>-int8.onnx``."""
    return Path(model).with_name(f"{Path(model).stem}-int8.onnx")


def export_onnx(weights: Path, out: Path, input_hw: tuple[int, int] = NAO_INPUT_HW, force: bool = False,
                extra: dict[str, Any] | None = None, dynamic: bool = False) -> Path:
    """Export ``weights`` (an Ultralytics segmentation .pt) to ONNX; returns ``out``.

    ``input_hw`` is the full frame's input size. ``dynamic`` lets the input height and width vary (multiples of
    32), so the front end can run the network on the band below the horizon alone (``LandmarkDetector``'s crop).
    """
    from ultralytics import YOLO

    weights, out = Path(weights), Path(out)
    if not weights.is_file():
        raise FileNotFoundError(f"{weights}: no such checkpoint - train one with `poles train`")
    check_output_file(out, force, (weights,))
    if any(side % 32 for side in input_hw):
        raise ValueError(f"--imgsz {input_hw[0]} {input_hw[1]}: both sides must be multiples of the stride 32")
    with tempfile.TemporaryDirectory(prefix="poles-export-") as scratch:
        copy = Path(scratch) / weights.name
        shutil.copyfile(weights, copy)
        model = YOLO(str(copy))
        if model.task != "segment":
            raise ValueError(f"{weights}: a {model.task} model, not a segmentation model - train a *-seg model")
        with _quiet_ultralytics():  # nms=None: the raw outputs, decoded by naoslam (False warns of a missing head)
            exported = Path(model.export(format="onnx", imgsz=list(input_hw), simplify=True, dynamic=dynamic,
                                         nms=None, device="cpu", verbose=False))
        names = model.names
        info = ModelInfo(tuple(names[i] for i in sorted(names)), tuple(input_hw), int(max(model.model.stride)),
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


def read_info(path: Path) -> ModelInfo:
    """The ModelInfo stored in an ONNX file; ValueError naming the file when it is not an ONNX model."""
    if not Path(path).is_file():
        raise FileNotFoundError(f"{path}: no such model file - export one with `poles export --weights best.pt`")
    try:
        proto = onnx.load(str(path), load_external_data=False)
    except Exception as exc:  # protobuf raises its own decode errors
        raise ValueError(f"{path}: not a readable ONNX model ({type(exc).__name__}) - re-export it with `poles export`") from None
    return ModelInfo.from_metadata({p.key: p.value for p in proto.metadata_props}, path)


def add_metadata(model: Path, **entries) -> Path:
    """Set extra entries (calibration, operating threshold) in ONNX ``model``'s naoslam metadata, in place, atomically.

    The weights are untouched."""
    info = read_info(model)
    return write_metadata(model, replace(info, extra={**info.extra, **entries}), model)


def write_metadata(source: Path, info: ModelInfo, out: Path) -> Path:
    """Copy ONNX ``source`` to ``out`` (atomically) with the naoslam entry set to ``info``."""
    proto = onnx.load(str(source))
    kept = [p for p in proto.metadata_props if p.key != METADATA_KEY]
    del proto.metadata_props[:]
    proto.metadata_props.extend(kept)
    proto.metadata_props.add(key=METADATA_KEY, value=info.to_json())
    with atomic_path(out) as tmp:
        onnx.save(proto, str(tmp))
    return Path(out)
