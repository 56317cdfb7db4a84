"""Install a trained pole model into the package: the checkpoint that ``poles train`` fine-tunes from, and the ONNX
exports that ``naoslam`` runs, each stamped with the range calibration and the operating confidence threshold.
The accurate model ships FP32 and INT8 ONNX (``make pole-model`` runs its recipe; this is its last step); the robot
model (``--robot``, ``make robot-model``) ships one FP32 ONNX, the faster precision at the Nao's instruction set."""
from __future__ import annotations

import argparse
import shutil
from dataclasses import replace
from pathlib import Path

from detector.model_files import load_calibration
from detector.model_files import ROBOT_WEIGHTS, SHIPPED_WEIGHTS
from detector.model_files import read_info, write_metadata
from export.onnx_export import int8_path
from detector.atomic import atomic_path
from naoslam.perception.pole_model import valid_confidence
from naoslam.shipped import OPERATING_CONF_KEY, robot_path, shipped_path

#: The most the shipped files may add to the repository, in bytes.
SIZE_BUDGET = 40 * 1024 * 1024


def shipped_files() -> list[Path]:
    """Every file the package ships of its models: the accurate model's checkpoint, FP32 and INT8 ONNX, then the
    robot model's checkpoint and ONNX."""
    return [SHIPPED_WEIGHTS, shipped_path(False), shipped_path(True), ROBOT_WEIGHTS, robot_path()]


def ship(weights: Path, onnx_fp32: Path, onnx_int8: Path, calibration_json: Path, operating_conf: float) -> list[Path]:
    """Install the accurate model: its checkpoint and both ONNX files, calibration and threshold in each."""
    return _install(weights, SHIPPED_WEIGHTS, [(onnx_fp32, shipped_path(False)), (onnx_int8, shipped_path(True))],
                    calibration_json, operating_conf)


def ship_robot(weights: Path, onnx_fp32: Path, calibration_json: Path, operating_conf: float) -> list[Path]:
    """Install the robot model: its checkpoint and its FP32 ONNX file with calibration and threshold."""
    return _install(weights, ROBOT_WEIGHTS, [(onnx_fp32, robot_path())], calibration_json, operating_conf)


def _install(weights: Path, weights_target: Path, onnx_files: list[tuple[Path, Path]], calibration_json: Path,
             operating_conf: float) -> list[Path]:
    """Copy the checkpoint and stamp each (source, target) ONNX pair; refuse a calibration measured at another input
    width, and a total over the budget."""
    valid_confidence(operating_conf)
    calibration = load_calibration(calibration_json)
    exported_width = read_info(onnx_files[0][0]).input_hw[1]
    if calibration.input_width not in (None, exported_width):
        raise ValueError(f"{calibration_json}: measured at {calibration.input_width} px input, the model is exported "
                         f"at {exported_width} px: calibrate it at its own size (leave out --imgsz)")
    weights_target.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(weights_target) as tmp:
        shutil.copyfile(weights, tmp)
    paths = [weights_target]
    for source, target in onnx_files:
        target.parent.mkdir(parents=True, exist_ok=True)
        info = read_info(source)
        extra = {**info.extra, "calibration": calibration.to_dict(), OPERATING_CONF_KEY: round(operating_conf, 3)}
        paths.append(write_metadata(source, replace(info, extra=extra), target))
    total = sum(p.stat().st_size for p in shipped_files() if p.is_file())
    if total > SIZE_BUDGET:
        raise ValueError(f"the shipped files take {total / 2**20:.1f} MiB, over the {SIZE_BUDGET / 2**20:.0f} MiB budget")
    return paths


def main(argv: list[str] | None = None) -> int:
    """Copy a trained model into the package (checkpoint, FP32 and INT8 ONNX) and print each file's size."""
    parser = argparse.ArgumentParser(prog="python -m export.ship", description=__doc__)
    parser.add_argument("--weights", type=Path, required=True, help="best.pt of the training run")
    parser.add_argument("--onnx", type=Path, required=True, help="its FP32 export (the INT8 copy is read beside it)")
    parser.add_argument("--robot", action="store_true", help="install it as the robot model (FP32 ONNX only)")
    parser.add_argument("--calibration", type=Path, required=True, help="calibration.json from `poles calibrate`")
    parser.add_argument("--conf", type=float, required=True, help="operating confidence threshold")
    args = parser.parse_args(argv)
    paths = ship_robot(args.weights, args.onnx, args.calibration, args.conf) if args.robot else \
        ship(args.weights, args.onnx, int8_path(args.onnx), args.calibration, args.conf)
    for path in paths:
        print(f"{path}: {path.stat().st_size / 2**20:.1f} MiB")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
