"""SLAM at the robot's rate: the same rendered walks through each front end, fed only the frames it would finish on
one Atom E3845 core, against the accurate model on every frame.

Each front end's whole run per frame is timed capped at the Atom's instruction set (``bench_robot.py``'s capped
worker, camera pose given); times 7 to 10 (the Atom basis in ``bench_robot.py``) it takes that long on the Atom, so of
the walk's camera frames it gets through one in ceil(Atom time / frame period), the slow end of the range. The
simulated walk's camera delivers ``SimConfig.frame_hz`` frames a second (tied to its odometry ticks), so a front end
faster than that sees every frame. EKF SLAM (``poles slam``'s defaults) runs on each; robot and landmark errors are
the means over the walks. The two-stage front end runs once more with its "maybe" tier (``--maybe``): detections
from that confidence up to its threshold reach the filter as tentative sightings, taken only where they confirm a
mapped landmark of their class inside the gate.
Usage: python benchmarks/bench_slam_rate.py [--seeds 3] [--maybe 0.4] [--before OLD_ROBOT.onnx]
"""
from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path

import numpy as np

os.environ.setdefault("YOLO_OFFLINE", "true")


def frames_kept(capped_ms: float, camera_hz: float, slowest_factor: float) -> int:
    """One camera frame in this many reaches the filter: the front end's Atom time over the frame period."""
    return max(1, math.ceil(capped_ms * slowest_factor / (1000.0 / camera_hz)))


def main() -> None:
    sys.path.insert(0, str(Path(__file__).parent))
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from bench_robot import speed_table
    from detector.speed import ATOM_FACTORS

    from detector.slam.sequences import FrontEndSpec, image_sequences
    from naoslam.ekf_slam import SlamConfig
    from naoslam.runner import run_slam
    from naoslam.sim import SimConfig

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--path", default="square")
    parser.add_argument("--before", help="the robot model the two-stage one replaced (ONNX)")
    parser.add_argument("--maybe", type=float, default=0.4, help="the two-stage front end's maybe tier's lower "
                        "threshold (default 0.4)")
    args = parser.parse_args()
    models = [("two-stage", "shipped-robot")] + ([("the one before", args.before)] if args.before else []) + \
        [("accurate INT8", "shipped-int8")]
    capped, _ = speed_table(models, 10, 2)
    camera_hz = SimConfig().frame_hz
    runs = [(label, FrontEndSpec(model), frames_kept(capped[f"{label}|openvino|pose"], camera_hz, ATOM_FACTORS[1]))
            for label, model in models]
    two_stage = next(every for label, _, every in runs if label == "two-stage")
    runs.insert(1, (f"two-stage, maybe from {args.maybe:g}", FrontEndSpec("shipped-robot", maybe_confidence=args.maybe),
                    two_stage))
    runs.append(("accurate INT8, every frame", FrontEndSpec("shipped-int8"), 1))
    errors: dict[str, list[tuple[float, float]]] = {}
    for seed in range(args.seeds):
        for every in sorted({every for _, _, every in runs}):
            config = SimConfig(path=args.path, seed=seed, front_end_hz=camera_hz / every if every > 1 else None)
            chosen = [(label, spec) for label, spec, e in runs if e == every]
            sequences = image_sequences(config, [spec for _, spec in chosen], progress=False)
            for (label, _), sequence in zip(chosen, sequences):
                result = run_slam(sequence, SlamConfig(), (0.01, 0.01, 0.01))
                errors.setdefault(label, []).append((result.metrics()["robot_error"]["mean"],
                                                     result.metrics()["landmark_error"]["mean"]))
    print(f"{args.path} walks, seeds 0-{args.seeds - 1}, camera {camera_hz:g} frames/s in the simulation; EKF SLAM, "
          "poles slam's defaults; capped ms per frame on this machine, x10 for the Atom's slow end")
    print("| front end | capped ms | Atom ms (x7-10) | frames reaching the filter | robot error (m) | "
          "landmark error (m) |")
    print("| --- | --- | --- | --- | --- | --- |")
    for label, model, every in runs:
        ms = capped[f"{label.split(',')[0]}|openvino|pose"]
        robot, landmark = np.mean(errors[label], axis=0)
        print(f"| {label} | {ms:.1f} | {ms * ATOM_FACTORS[0]:.0f}-{ms * ATOM_FACTORS[1]:.0f} | "
              f"1 in {every} ({camera_hz / every:g}/s) | {robot:.3f} | {landmark:.3f} |")


if __name__ == "__main__":
    main()
