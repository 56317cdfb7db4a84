"""The front ends ``poles evaluate`` compares, behind one interface: frame -> detections
(``naoslam.perception.detections.Detection``, best first): naoslam's detectors, and a trained checkpoint on PyTorch."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from detector.model_files import read_checkpoint, run_checkpoint, ultralytics_frame
from naoslam.camera import CameraPose
from naoslam.perception.detections import Detection
from naoslam.perception.loading import load_detector
from naoslam.measurement import RangeCalibration
from naoslam.shipped import COLOUR_FILTER, resolve_model

#: Lowest confidence kept, so that the precision/recall sweep and mAP see every detection.
SWEEP_CONF = 0.01


class Predictor:
    """A front end under evaluation."""

    name: str = ""
    calibration: RangeCalibration | None = None
    #: The confidence threshold the front end is meant to run at (stored in the model), if it has one.
    operating_conf: float | None = None
    #: How a detection is matched to a label (``counting.MATCHINGS``): by its mask, its box (a box-only front end,
    #: or any front end scored as one) or its band-dividing point (the colour filter).
    matching: str = "mask"

    def __call__(self, frame: np.ndarray, camera_pose: CameraPose | None = None) -> list[Detection]:
        """The detections in one frame; a front end that uses the camera's pose (the ONNX ones) gets it."""
        raise NotImplementedError


class RuntimePredictor(Predictor):
    """A naoslam detector (``naoslam.load_detector``'s): an exported model (FP32 or INT8, at ``input_width`` if
    given), the robot's two-stage model (boxes, matched by box IoU) or the colour filter (matched by its
    band-dividing point).

    Ranges come from ``calibration``, else from the detector's own one where it holds at this input width.
    """

    def __init__(self, model: Path | str, input_width: int | None = None,
                 calibration: RangeCalibration | None = None):
        self.detector = load_detector(model, conf=SWEEP_CONF, input_width=input_width)
        self.name = Path(model).name
        self.matching = self.detector.matching
        self.calibration = (self.detector.check_calibration(calibration) if calibration is not None
                            else self.detector.usable_calibration)
        self.operating_conf = self.detector.stored_conf

    def __call__(self, frame: np.ndarray, camera_pose: CameraPose | None = None) -> list[Detection]:
        return self.detector(frame, camera_pose)


class TorchPredictor(Predictor):
    """A trained checkpoint run by Ultralytics on PyTorch (full-resolution masks)."""

    def __init__(self, path: Path, imgsz: int = 640):
        from ultralytics import YOLO  # deferred: Ultralytics and torch load only when a checkpoint is evaluated

        self.model = YOLO(str(path))
        if self.model.task != "segment":
            raise ValueError(f"{path}: a {self.model.task} model, not a segmentation model - evaluate a *-seg "
                             "checkpoint (masks are what the thesis counted)")
        self.imgsz = imgsz
        self.name = Path(path).name

    def __call__(self, frame: np.ndarray, camera_pose: CameraPose | None = None) -> list[Detection]:

        return ultralytics_frame(self.model, frame, self.imgsz, SWEEP_CONF)


def make_predictor(model: str, imgsz: int | None = None, calibration: RangeCalibration | None = None) -> Predictor:
    """``colour-filter``, ``shipped`` / ``shipped-int8`` / ``shipped-robot`` (the models in naoslam), a ``.pt`` checkpoint (or the run
    folder that holds it) or an ``.onnx``.

    ``imgsz``: the network's input width (default: 640 for a checkpoint, an ONNX model's own).
    """
    if model == COLOUR_FILTER:
        return RuntimePredictor(model, imgsz, calibration)
    path = run_checkpoint(resolve_model(model))
    if path.suffix == ".onnx":
        return RuntimePredictor(path, imgsz, calibration)
    if path.suffix != ".pt":
        raise ValueError(f"--model {model!r}: give a .pt checkpoint (or its run folder), an .onnx model, `shipped` or "
                         "`colour-filter`")
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such checkpoint")
    read_checkpoint(path)  # an empty or garbled file is refused in one line naming it, before Ultralytics sees it
    predictor = TorchPredictor(path, imgsz or 640)
    predictor.calibration = calibration
    return predictor
