"""The robot model: the two-stage front end shipped, reachable by every name a command takes, measuring as the
accurate model does, and runnable at the Atom's instruction set; the robot-sized YOLOv8 architectures still train."""
from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import onnx
import pytest

from naoslam.perception.two_stage import CropDetector
from naoslam.perception.yolo import LandmarkDetector
from naoslam.perception.loading import load_detector
from naoslam.front_end import FrontEnd
from naoslam.measurement import Measurement
from naoslam.shipped import OPERATING_CONF_KEY, resolve_model, robot_path, shipped_path
from tests.conftest import rendered_pole


def test_the_robot_name_opens_the_two_stage_front_end():
    detector = load_detector("shipped-robot")
    assert isinstance(detector, CropDetector) and detector.path == robot_path()
    assert resolve_model("shipped-robot") == robot_path() and load_detector("shipped").path == shipped_path()
    with pytest.raises(ValueError, match="two-stage robot model"):
        LandmarkDetector("shipped-robot")


def test_the_robot_model_carries_its_calibration_threshold_and_training_record():
    detector = load_detector("shipped-robot")
    assert 0.0 < detector.info.extra[OPERATING_CONF_KEY] < 1.0 and detector.conf == detector.stored_conf
    calibration = detector.calibration  # measured on its own boxes, in the frame's pixels
    assert calibration.input_width is None and calibration.width_law.b < 0 and calibration.height_law.b < 0
    training = detector.info.extra["training"]
    assert training["minutes"] > 0 and "cores" in training["hardware"]


@pytest.mark.parametrize("model", ["shipped-robot", "shipped-int8"])
def test_front_end_ranges_a_rendered_pole_within_the_calibrations_error(model):
    image, _ = rendered_pole("gp", 2.0, 0.0, seed=5)
    front_end = FrontEnd(model)
    (measurement,) = front_end(image)
    assert measurement.signature == "gp"
    # Three of the calibration's own standard deviations: a wrong law or input width misses by far more.
    assert abs(measurement.range_m - 2.0) < 3 * measurement.range_std
    assert abs(measurement.bearing_rad) < np.radians(3)
    assert measurement.detection.name == "gp"


def test_the_colour_filter_and_the_models_give_the_same_measurement():
    image, _ = rendered_pole("pb", 1.5, 0.0, seed=8)
    found = {name: FrontEnd(name)(image) for name in ("colour-filter", "shipped-robot", "shipped")}
    assert all(len(measurements) == 1 for measurements in found.values()), found
    assert {type(measurements[0]) for measurements in found.values()} == {Measurement}
    assert {measurements[0].signature for measurements in found.values()} == {"pb"}
    robot, accurate = found["shipped-robot"][0], found["shipped"][0]
    assert robot.detection.box_only and not accurate.detection.box_only
    assert abs(robot.range_m - accurate.range_m) < 3 * robot.range_std
    assert abs(robot.bearing_rad - accurate.bearing_rad) < np.radians(1)


def test_the_robot_model_compiles_at_the_atom_s_instruction_set():
    """OpenVINO's CPU plugin finds no SSE4.1 primitive for some operators (Resize); the crop network has none."""
    code_run = ("from naoslam.perception.engines import OpenVinoForward; import numpy as np; "
                f"OpenVinoForward({str(robot_path())!r}, 1)(np.zeros((1, 3, 48, 24), np.float32)); print('compiled')")
    result = subprocess.run([sys.executable, "-c", code_run], capture_output=True, text=True,
                            env={**os.environ, "ONEDNN_MAX_CPU_ISA": "SSE41"})
    assert result.returncode == 0 and "compiled" in result.stdout, result.stderr[-2000:]


def test_a_robot_architecture_trains_exports_and_runs_in_the_front_end(synth_dataset, tmp_path):
    """`poles train --model robot-p4-seg` builds the package's YAML (strides 8 and 16, 16 prototypes); its export
    is rewritten for the Atom (no Resize or ConvTranspose: expand, pixel shuffle) and the front end reads its smaller
    segmentation head. An input off Ultralytics' 32-pixel grid (its stride is 16) is checked at the grid's size."""
    from detector.cli import main

    run = tmp_path / "run"
    assert main(["train", "--data", str(synth_dataset), "--out", str(run), "--model", "robot-p4-seg", "--epochs", "1",
                 "--imgsz", "64", "--batch", "8"]) == 0
    assert main(["export", "--weights", str(run), "--out", str(tmp_path / "robot.onnx"), "--imgsz", "48", "64",
                 "--dynamic", "--data", str(synth_dataset)]) == 0
    detector = LandmarkDetector(tmp_path / "robot.onnx")
    assert detector.info.stride == 16 and detector.input_hw == (48, 64)
    assert detector.session.get_outputs()[1].shape[1] == 16
    operators = {node.op_type for node in onnx.load(str(tmp_path / "robot.onnx")).graph.node}
    assert not operators & {"Resize", "ConvTranspose"} and "DepthToSpace" in operators
    assert isinstance(detector(np.zeros((240, 320, 3), np.uint8)), list)
