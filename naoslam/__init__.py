"""naoslam: the runtime that turns pole detections into range/bearing measurements and runs EKF SLAM.

Runs on the robot: imports only numpy, OpenCV and onnxruntime - never torch, ultralytics or the training side.

The names a robot program needs are importable from the package itself (``naoslam.LandmarkDetector()``); each is
loaded on first use, so ``import naoslam`` stays cheap and a module that needs only the filters never loads
onnxruntime.
"""
from __future__ import annotations

import importlib

#: Public name -> the module that defines it.
_PUBLIC = {
    "FrontEnd": "naoslam.front_end",
    "LandmarkDetector": "naoslam.perception.yolo",
    "CropDetector": "naoslam.perception.two_stage",
    "load_detector": "naoslam.perception.loading",
    "PoleDetector": "naoslam.perception.interface",
    "Detection": "naoslam.perception.detections",
    "shipped_model": "naoslam.shipped",
    "shipped_calibration": "naoslam.perception.pole_model",
    "RangeCalibration": "naoslam.measurement",
    "MeasurementModel": "naoslam.measurement",
    "Measurement": "naoslam.measurement",
    "EkfSlam": "naoslam.ekf_slam",
    "SlamConfig": "naoslam.ekf_slam",
    "EkfLocalisation": "naoslam.localisation",
    "EifLocalisation": "naoslam.localisation",
}

__all__ = sorted(_PUBLIC)


def __getattr__(name: str):
    """Load a public name from its module on first use (PEP 562)."""
    if name not in _PUBLIC:
        raise AttributeError(f"module 'naoslam' has no attribute {name!r}")
    value = getattr(importlib.import_module(_PUBLIC[name]), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_PUBLIC))
