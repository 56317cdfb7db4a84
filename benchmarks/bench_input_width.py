"""The input width a slow CPU can afford: the shipped pole model run smaller (``LandmarkDetector(input_width=W)``),
ms per 640x480 frame against the model's own 640 px input in the same run, FP32 and INT8, whole frame and the band
below the horizon, one onnxruntime thread (a vision thread on one core).

What each width costs in poles found is measured with ``poles evaluate --imgsz W`` (docs/camera-pose.md, "Engines
and the on-robot budget"); this benchmark measures only time, and counts the detections on the same frames as a check.
Frames: a rendered walk (camera pose known, so the band is the one the robot would crop).
Usage: python benchmarks/bench_input_width.py [FRAMES] [REPEATS]
"""
from __future__ import annotations

import sys

from bench_engines import timed, walk_frames

WIDTHS = (640, 480, 416, 320)


def main(count: int, repeats: int) -> None:
    from naoslam.perception.yolo import LandmarkDetector
    from naoslam.shipped import shipped_path

    frames, poses = walk_frames(count)
    print(f"shipped yolov8n-seg, {count} walk frames, {repeats} passes, one thread")
    print("| model | input | input width | network input (whole frame) | ms per frame | / 640 px | detections |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for precision, int8 in (("FP32", False), ("INT8", True)):
        for crop in (False, True):
            baseline = None
            for width in WIDTHS:
                detector = LandmarkDetector(shipped_path(int8), threads=1, input_width=width)
                ms = timed(lambda f, p: detector(f, p, crop=crop), frames, poses, repeats)
                baseline = baseline or ms
                found = sum(len(detector(f, p, crop=crop)) for f, p in zip(frames, poses))
                hw = detector.input_hw
                print(f"| {precision} | {'band' if crop else 'whole'} | {width} | {hw[1]}x{hw[0]} | {ms:.1f} | "
                      f"{ms / baseline:.2f} | {found} |", flush=True)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 20, int(sys.argv[2]) if len(sys.argv) > 2 else 3)
