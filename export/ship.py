"""Install a trained pole model into the package: the checkpoint that ``poles train`` fine-tunes from, and the ONNX
FP32 and INT8 exports that ``naoslam`` runs by default, each stamped with the range calibration and the operating
confidence threshold. ``make pole-model`` runs the whole recipe; this is its last step."""
from __future__ import annotations

import argparse
import shutil
from dataclasses import replace
from pathlib import Path

from calibration.run import load_calibration
from detector.training.starting_point import SHIPPED_WEIGHTS
from export.onnx_export import int8_path, read_info, write_metadata
from naoslam.atomic import atomic_path
from naoslam.detector import valid_confidence
from naoslam.shipped import OPERATING_CONF_KEY, shipped_path

#: The most the shipped files may add to the repository, in bytes.
SIZE_BUDGET = 40 * 1024 * 1024


def ship(weights: Path, onnx_fp32: Path, onnx_int8: Path, calibration_json: Path, operating_conf: float) -> list[Path]:
    """Copy the three files into the package with calibration and threshold in both ONNX files; returns their paths."""
    valid_confidence(operating_conf)
    calibration = load_calibration(calibration_json)
    exported_width = read_info(onnx_fp32).input_hw[1]
    if calibration.input_width not in (None, exported_width):
        raise ValueError(f"{calibration_json}: measured at {calibration.input_width} px input, the model is exported "
                         f"at {exported_width} px: calibrate it at its own size (leave out --imgsz)")
    SHIPPED_WEIGHTS.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(SHIPPED_WEIGHTS) as tmp:
        shutil.copyfile(weights, tmp)
    paths = [SHIPPED_WEIGHTS]
    for source, int8 in ((onnx_fp32, False), (onnx_int8, True)):
        target = shipped_path(int8)
        target.parent.mkdir(parents=True, exist_ok=True)
        info = read_info(source)
        extra = {**info.extra, "calibration": calibration.to_dict(), OPERATING_CONF_KEY: round(operating_conf, 3)}
        paths.append(write_metadata(source, replace(info, extra=extra), target))
    total = sum(p.stat().st_size for p in paths)
    if total > SIZE_BUDGET:
        raise ValueError(f"the shipped files take {total / 2**20:.1f} MiB, over the {SIZE_BUDGET / 2**20:.0f} MiB budget")
    return paths


def main(argv: list[str] | None = None) -> int:
    """Copy a trained model into the package (checkpoint, FP32 and INT8 ONNX) and print each file's size."""
    parser = argparse.ArgumentParser(prog="python -m export.ship", description=__doc__)
    parser.add_argument("--weights", type=Path, required=True, help="best.pt of the training run")
    parser.add_argument("--onnx", type=Path, required=True, help="its FP32 export (the INT8 copy is read beside it)")
    parser.add_argument("--calibration", type=Path, required=True, help="calibration.json from `poles calibrate`")
    parser.add_argument("--conf", type=float, required=True, help="operating confidence threshold")
    args = parser.parse_args(argv)
    for path in ship(args.weights, args.onnx, int8_path(args.onnx), args.calibration,
                     args.conf):
        print(f"{path}: {path.stat().st_size / 2**20:.1f} MiB")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
