"""The one shape of "frame to detections" in naoslam. The YOLOv8-seg detector (``LandmarkDetector``), the robot's
two-stage front end (``CropDetector``) and the colour filter (``ColourFilter``) all have it; ``load_detector`` opens
any of them by name, and ``FrontEnd`` and ``poles evaluate`` take any of them."""
from __future__ import annotations

from typing import Protocol

import numpy as np

from naoslam.camera import CameraPose
from naoslam.perception.detections import Detection
from naoslam.ground import GroundView
from naoslam.measurement import RangeCalibration


class PoleDetector(Protocol):
    """A frame in (BGR; YUYV where the detector reads it), with the camera's pose or the frame's ground view already
    built when known; the poles found out, best first.

    ``matching``: how its detections are compared with labels (``mask``, ``box`` for a front end without masks,
    ``point`` for the colour filter's band-dividing point). ``conf``: the confidence it keeps detections from.
    """

    matching: str
    conf: float

    def __call__(self, frame: np.ndarray, camera_pose: CameraPose | None = None,
                 view: GroundView | None = None) -> list[Detection]: ...

    @property
    def stored_conf(self) -> float | None:
        """The threshold the detector was shipped to run at (None: none stored)."""

    @property
    def calibration(self) -> RangeCalibration | None:
        """The range calibration its detections are measured with (None: it has none)."""

    @property
    def usable_calibration(self) -> RangeCalibration | None:
        """Its calibration where it holds for this detector as it runs, else None."""

    def check_calibration(self, calibration: RangeCalibration) -> RangeCalibration:
        """``calibration``, or a ValueError naming the fix when it cannot measure this detector's detections."""
