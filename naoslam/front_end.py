"""From a camera frame to the EKF's measurements in one call: detector, ground-plane gate and measurement model.

``FrontEnd("shipped-robot")(frame, camera_pose)`` runs the pole model, drops what cannot stand on the floor, and turns
each mask into range and bearing with the model's calibration; ``FrontEnd("colour-filter")`` does the same with the
colour filter and its band-spacing law. The frame's ground view is built once and shared by the gate and the ranges.
"""
from __future__ import annotations

import numpy as np

from naoslam.camera import CameraPose
from naoslam.colour_filter import ColourFilter
from naoslam.measurement import THESIS_CONF, Measurement, MeasurementModel, RangeCalibration, bearing_of_column

#: The name that stands for the colour filter wherever a model is asked for.
COLOUR_FILTER = "colour-filter"


class FrontEnd:
    """Frames in, measurements out.

    ``model``: a shipped model's name (``shipped``, ``shipped-int8``, ``shipped-robot``), an ONNX path, a
    detector already made (``load_detector``'s), or ``colour-filter``. ``calibration`` None uses the one stored in the model
    (the shipped model's for the colour filter). ``min_confidence`` None uses the model's operating threshold, else
    the thesis's 0.85. ``input_width`` runs a ``--dynamic`` model at that width; ``threads`` and ``engine``
    (``onnxruntime`` or ``openvino``) as ``load_detector``.
    """

    def __init__(self, model="shipped", calibration: RangeCalibration | None = None,
                 min_confidence: float | None = None, input_width: int | None = None, threads: int | None = None,
                 engine: str = "onnxruntime"):
        if model == COLOUR_FILTER:
            self.detector, self.calibration = None, _colour_calibration(calibration)
            self._colour_filter = ColourFilter()
            return
        from naoslam.detector import load_detector
        from naoslam.pole_model import PoleModel

        self.detector = model if isinstance(model, PoleModel) else \
            load_detector(model, input_width=input_width, threads=threads, engine=engine)
        threshold = min_confidence if min_confidence is not None else self.detector.stored_conf or THESIS_CONF
        self.detector.conf = min(self.detector.conf, threshold)
        self.calibration = self.detector.check_calibration(calibration) if calibration else self.detector.calibration
        if self.calibration is None:
            raise ValueError(f"{self.detector.path}: no calibration in the model - run `poles calibrate --embed` or "
                             "pass calibration=")
        self.measurement_model = MeasurementModel(self.calibration, threshold)

    def __call__(self, frame: np.ndarray, camera_pose: CameraPose | None = None) -> list[Measurement]:
        """Measurements of the poles in one BGR frame; with the camera's pose (height, pitch, roll), the ground-plane
        gate, the horizon band and the foot-row range are used (model front ends only)."""
        return self.detect_and_measure(frame, camera_pose)[1]

    def detect_and_measure(self, frame: np.ndarray, camera_pose: CameraPose | None = None) -> tuple[list, list]:
        """The frame's detections (those the gate kept) and the measurements made of them, for a caller that also
        shows what was found (an overlay)."""
        if self.detector is None:
            found = self._colour_filter(frame)
            return found, self._colour_measurements(frame, found)
        view = self.detector.ground_view(frame.shape[:2], camera_pose) if camera_pose is not None else None
        found = self.detector(frame, camera_pose, view=view)
        return found, self.measurement_model.measure(found, frame.shape[1], view=view)

    def _colour_measurements(self, frame: np.ndarray, found: list) -> list[Measurement]:
        width, out = frame.shape[1], []
        for d in found:
            range_m, range_std = self.calibration.colour_range(d.band_distance_px, width, column=d.centre_column)
            out.append(Measurement(range_m, bearing_of_column(d.centre_column, width, self.calibration.hfov_deg),
                                   d.name, 1.0, range_std, self.calibration.bearing_std_rad, "colour filter", d))
        return out


def _colour_calibration(calibration: RangeCalibration | None) -> RangeCalibration:
    """The colour filter's calibration: the one given, else the shipped model's (the same camera's colour law)."""
    if calibration is None:
        from naoslam.detector import shipped_calibration

        calibration = shipped_calibration()
    if calibration is None or calibration.colour_law is None:
        raise ValueError("the colour filter needs a colour law and the calibration has none: leave the calibration "
                         "out to use the shipped one, or fit one with `poles calibrate` on poles of known range")
    return calibration
