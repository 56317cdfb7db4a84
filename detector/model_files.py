"""Reading the files a model lives in, for every stage: where the shipped checkpoints are and which checkpoint a run
folder stands for, a checkpoint (``read_checkpoint``), an ONNX model's naoslam metadata (``read_info``,
``write_metadata``, ``add_metadata``), a calibration.json (``load_calibration``) and a checkpoint's own answers
through Ultralytics (``ultralytics_predict``), which export verification and evaluation both compare against."""
from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import onnx

from detector.atomic import atomic_path
from detector.formats import read_record
from naoslam.perception.detections import Detection
from naoslam.measurement import RangeCalibration
from naoslam.perception.model_info import METADATA_KEY, ModelInfo

#: The pole-pretrained checkpoint shipped with the package (the source of naoslam's shipped accurate models).
SHIPPED_WEIGHTS = Path(__file__).resolve().parent / "weights" / "poles-yolov8n-seg.pt"
#: The robot front end's crop network checkpoint (the source of naoslam's ``shipped-robot``); train it on with
#: ``poles train-robot --weights``.
ROBOT_WEIGHTS = SHIPPED_WEIGHTS.with_name("poles-robot.pt")


def run_checkpoint(path: str | Path) -> Path:
    """A ``poles train`` run folder stands for its ``weights/best.pt``; any other path is returned as given."""
    best = Path(path) / "weights" / "best.pt"
    return best if Path(path).is_dir() and best.is_file() else Path(path)


def load_calibration(path: Path) -> RangeCalibration:
    """Read calibration.json (as written by ``poles calibrate``); any other file is refused in one line naming it."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such calibration file - write one with `poles calibrate`")
    data = read_record(path, "calibration")
    try:
        return RangeCalibration.from_dict(data.get("calibration", data))
    except (ValueError, AttributeError, KeyError, TypeError) as error:  # ValueError: the laws' checks
        raise ValueError(f"{path}: not a calibration written by `poles calibrate` ({type(error).__name__}: {error}) "
                         "- write one with `poles calibrate`") from None




def read_checkpoint(path: Path) -> dict:
    """A local Ultralytics checkpoint as a dict (plain torch.load on the CPU: never a download)."""
    import torch  # deferred, as Ultralytics below: the ONNX side of this module needs neither

    if not Path(path).is_file():
        raise FileNotFoundError(f"{path}: no such checkpoint - pass a best.pt or last.pt written by `poles train`")
    try:
        checkpoint = torch.load(str(path), map_location="cpu", weights_only=False)
    except Exception as exc:  # torch raises pickle, zip and runtime errors for files that are not checkpoints
        raise ValueError(f"{path}: not a readable PyTorch checkpoint ({type(exc).__name__}) - "
                         "pass a best.pt or last.pt written by `poles train`") from None
    if not isinstance(checkpoint, dict) or "model" not in checkpoint and "ema" not in checkpoint:
        raise ValueError(f"{path}: not an Ultralytics checkpoint (no model inside) - pass a .pt written by `poles train`")
    return checkpoint


def ultralytics_predict(model: Path, frames: list[np.ndarray], input_hw: tuple[int, int],
                        conf: float) -> list[list[Detection]]:
    """Ultralytics' own predictions (a .pt on PyTorch, or an .onnx through its AutoBackend) with full-size masks."""
    from ultralytics import YOLO

    predictor = YOLO(str(model), task="segment")
    return [ultralytics_frame(predictor, frame, list(input_hw), conf) for frame in frames]


def ultralytics_frame(predictor, frame: np.ndarray, imgsz: int | list[int], conf: float) -> list[Detection]:
    """One frame through a loaded Ultralytics model, masks at the frame's resolution (``retina_masks``)."""
    result = predictor.predict(frame, imgsz=imgsz, conf=conf, retina_masks=True, device="cpu", verbose=False)[0]
    return Detection.from_ultralytics(result, frame.shape)


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
