"""From a camera frame to the EKF's measurements in one call: detector, ground-plane gate and measurement model.

``FrontEnd("shipped-robot")(frame, camera_pose)`` runs the pole model, drops what cannot stand on the floor, and turns
each detection into range and bearing with the model's calibration; ``FrontEnd("colour-filter")`` does the same with
the colour filter and its band-spacing law. The frame's ground view is built once and shared by the gate and the
ranges.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from naoslam.camera import CameraPose, PinholeCamera
from naoslam.perception.loading import load_detector
from naoslam.ground import GroundView
from naoslam.measurement import THESIS_CONF, Measurement, MeasurementModel, RangeCalibration
from naoslam.perception.interface import PoleDetector


class FrontEnd:
    """Frames in, measurements out.

    ``model``: a name ``load_detector`` knows (``shipped``, ``shipped-int8``, ``shipped-robot``, ``colour-filter``),
    an ONNX path, or a detector already made (a ``PoleDetector``). ``calibration`` None uses the detector's own (the
    shipped model's colour law for the colour filter). ``min_confidence`` None uses the model's operating threshold,
    else the thesis's 0.85. ``maybe_confidence``: detections between it and that threshold become tentative
    measurements, which a filter takes only where they confirm a mapped landmark of their class (None: none).
    ``input_width`` runs a ``--dynamic`` model at that width; ``threads`` and ``engine`` (``onnxruntime`` or
    ``openvino``) as ``load_detector``.
    """

    def __init__(self, model: str | Path | PoleDetector = "shipped", calibration: RangeCalibration | None = None,
                 min_confidence: float | None = None, input_width: int | None = None, threads: int | None = None,
                 engine: str = "onnxruntime", maybe_confidence: float | None = None):
        self.detector: PoleDetector = load_detector(model, input_width=input_width, threads=threads, engine=engine) \
            if isinstance(model, (str, Path)) else model
        threshold = min_confidence if min_confidence is not None else self.detector.stored_conf or THESIS_CONF
        self.detector.conf = min(self.detector.conf, threshold, maybe_confidence or threshold)
        self.calibration = self.detector.check_calibration(calibration) if calibration else self.detector.calibration
        if self.calibration is None:
            raise ValueError(f"{model}: no calibration in the model - run `poles calibrate --embed` or pass "
                             "calibration=")
        self.measurement_model = MeasurementModel(self.calibration, threshold, maybe_confidence=maybe_confidence)

    def __call__(self, frame: np.ndarray, camera_pose: CameraPose | None = None) -> list[Measurement]:
        """Measurements of the poles in one BGR frame; with the camera's pose (height, pitch, roll), the ground-plane
        gate, the horizon band and the foot-row range are used (model front ends only)."""
        return self.detect_and_measure(frame, camera_pose)[1]

    def detect_and_measure(self, frame: np.ndarray, camera_pose: CameraPose | None = None) -> tuple[list, list]:
        """The frame's detections (those the gate kept) and the measurements made of them, for a caller that also
        shows what was found (an overlay)."""
        height, width = frame.shape[:2]
        view = None if camera_pose is None else \
            GroundView(PinholeCamera(width, height, self.calibration.hfov_deg), camera_pose)
        found = self.detector(frame, camera_pose, view=view)
        return found, self.measurement_model.measure(found, width, view=view)
