"""The on-robot budget: the shipped pole model per 640x480 frame, for each engine, precision, input (whole frame or the
band below the horizon) and thread count, against Ultralytics' predict, in one run.

Engines: onnxruntime (naoslam's default) and OpenVINO (``LandmarkDetector(engine="openvino")``; Intel's runtime, and
the Nao's CPU is an Intel Atom; f32 precision hint) on the shipped FP32 and QDQ INT8 models, and OpenVINO on its own
INT8 model quantised by NNCF. Every engine
feeds the same front end (``LandmarkDetector``'s preparation, decoding, masks and ground-plane gate), so the
differences are the forward pass. Agreement: detections of each engine against onnxruntime FP32 on the same frames
(count, classes, largest box corner difference). Reference: Ultralytics ``YOLO(best.pt).predict`` on the whole
frame with the same number of torch threads.
The colour filter's time per frame closes the table.
Frames: a rendered walk (camera pose known, so the band is the one the robot would crop).
Usage: python benchmarks/bench_engines.py [FRAMES] [REPEATS]
"""
from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import numpy as np

os.environ.setdefault("YOLO_OFFLINE", "true")


def walk_frames(count: int):
    """(frames, camera poses) of a rendered walk, ``count`` frames spread over it."""
    from detector.synth.walk import render_walk, walk_camera_poses
    from naoslam.sim import SimConfig, simulate

    walk = simulate(SimConfig(seed=3, duration_s=60))
    frames, poses = render_walk(walk, seed=3, progress=False), walk_camera_poses(walk, 3)
    picks = np.linspace(0, len(frames) - 1, count).round().astype(int)
    return [frames[i] for i in picks], [poses[i] for i in picks]


def nncf_int8(fp32: Path, blobs: list[np.ndarray]):
    """OpenVINO's own INT8 path: NNCF post-training quantisation of the FP32 model (mixed preset, the decode head's
    arithmetic ignored as the onnxruntime copy does)."""
    import nncf
    import onnx
    import openvino as ov

    from export.quantize import decode_head_nodes

    model = ov.Core().read_model(str(fp32))
    ignored = nncf.IgnoredScope(names=decode_head_nodes(onnx.load(str(fp32), load_external_data=False)),
                                validate=False)
    return nncf.quantize(model, nncf.Dataset(blobs), preset=nncf.QuantizationPreset.MIXED, ignored_scope=ignored,
                         subset_size=len(blobs))


def timed(run, frames, poses, repeats: int) -> float:
    """Median ms per frame of ``run(frame, pose)`` over ``repeats`` passes (one warm-up pass first)."""
    for f, p in zip(frames, poses):
        run(f, p)
    times = []
    for _ in range(repeats):
        for f, p in zip(frames, poses):
            start = time.perf_counter()
            run(f, p)
            times.append(time.perf_counter() - start)
    return 1000 * float(np.median(times))


def agreement(reference: list, other: list) -> str:
    same = sum(len(a) == len(b) and [d.name for d in a] == [d.name for d in b] for a, b in zip(reference, other))
    corners = [np.abs(np.subtract(x.box, y.box)).max() for a, b in zip(reference, other) if len(a) == len(b)
               for x, y in zip(a, b)]
    return f"{same}/{len(reference)} frames alike, box corners within {max(corners, default=0):.1f} px"


def main(count: int, repeats: int) -> None:
    import torch
    from ultralytics import YOLO
    from ultralytics.utils.torch_utils import get_flops

    from detector.model_files import SHIPPED_WEIGHTS
    from naoslam.camera import PinholeCamera
    from naoslam.perception.colour_filter import ColourFilter
    from naoslam.perception.yolo import LandmarkDetector
    from naoslam.perception.engines import OpenVinoForward
    from naoslam.ground import GroundView
    from naoslam.shipped import shipped_path

    frames, poses = walk_frames(count)
    fp32, int8 = shipped_path(False), shipped_path(True)
    pytorch = YOLO(str(SHIPPED_WEIGHTS))
    gflops_full = get_flops(pytorch.model, [480, 640])
    probe = LandmarkDetector(fp32)
    band_rows = [frames[0].shape[0] - GroundView(PinholeCamera(), p).band_top() for p in poses]
    band_hw = probe.band_input_hw((480, 640), int(np.median(band_rows)))
    print(f"shipped yolov8n-seg: {gflops_full:.1f} GFLOPs at 480x640, about {gflops_full * band_hw[0] / 480:.1f} at "
          f"the median band {band_hw[0]}x{band_hw[1]} (any input size: {probe.any_input_size}); {count} walk frames, "
          f"{repeats} passes")
    blobs = [probe.prepare(f)[0] for f in frames]
    nncf_model = nncf_int8(fp32, blobs)
    rows = []
    for threads in (1, 2):
        torch.set_num_threads(threads)
        ultralytics = timed(lambda f, p: pytorch.predict(f, imgsz=[480, 640], conf=0.55, verbose=False), frames,
                            poses, repeats)
        rows.append(("Ultralytics predict (PyTorch)", "FP32", "whole", threads, ultralytics, ultralytics, "-"))
        reference = None
        for engine in ("onnxruntime", "OpenVINO"):
            for precision, path in (("FP32", fp32), ("INT8 (QDQ)", int8), ("INT8 (NNCF)", None)):
                if engine == "onnxruntime" and path is None:
                    continue
                detector = LandmarkDetector(path or fp32, threads=threads,
                                            engine="openvino" if engine == "OpenVINO" else "onnxruntime")
                if path is None:  # NNCF's model exists only in memory: put it behind the same engine
                    detector._openvino = OpenVinoForward(nncf_model, threads)
                for crop in (False, True):
                    ms = timed(lambda f, p: detector(f, p, crop=crop), frames, poses, repeats)
                    found = [detector(f, p, crop=crop) for f, p in zip(frames, poses)]
                    if reference is None:
                        reference = found
                    rows.append((engine, precision, "band" if crop else "whole", threads, ms, ultralytics,
                                 agreement(reference, found)))
    colour_filter = ColourFilter()
    colour_ms = timed(lambda f, p: colour_filter(f), frames, poses, repeats)
    rows.append(("colour filter (thesis baseline, no network)", "-", "whole", 1, colour_ms, rows[0][5], "-"))
    print("| engine | precision | input | threads | ms per frame | / Ultralytics predict | answers vs onnxruntime "
          "FP32 whole frame |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for engine, precision, crop, threads, ms, ultralytics, agrees in rows:
        print(f"| {engine} | {precision} | {crop} | {threads} | {ms:.1f} | {ms / ultralytics:.2f} | {agrees} |")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 20, int(sys.argv[2]) if len(sys.argv) > 2 else 3)
