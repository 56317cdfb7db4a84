"""Front-end latency per 640x480 frame against the bare forward pass and against Ultralytics' predict.

Same ONNX file, same frames, runs interleaved in one process: (a) ``session.run`` on an already prepared tensor,
(b) ``LandmarkDetector`` (prepare + run + decode + masks + rotated boxes), (c) Ultralytics ``YOLO(onnx).predict``,
and (d) the front end's own work alone (prepare + decode on stored network outputs), which is its overhead
without the run-to-run noise of the forward pass.
Models are built from their YAML (untrained); the confidence threshold is set per model so that a frame gives about
five detections, as a frame full of poles would, so decoding and masks are paid for.
Usage: python benchmarks/bench_frontend.py [FRAMES] [MODEL ...]
"""
from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

os.environ.setdefault("YOLO_OFFLINE", "true")

DETECTIONS_PER_FRAME = 5


def build_onnx(model: str, folder: Path, images: list[Path]) -> Path:
    """An untrained model (batch-norm statistics estimated on ``images``) exported at 480x640."""
    import torch
    from ultralytics.nn.tasks import SegmentationModel

    from detector.training.train import recalibrate_batchnorm
    from export.onnx_export import export_onnx
    from naoslam.landmarks import CLASSES

    checkpoint = folder / f"{model}.pt"
    network = SegmentationModel(f"{model}.yaml", nc=len(CLASSES), verbose=False)
    network.names = dict(enumerate(CLASSES))
    torch.save({"model": network.half(), "train_args": {"task": "segment"}, "epoch": -1}, checkpoint)
    recalibrate_batchnorm(checkpoint, images, (480, 640), checkpoint)
    return export_onnx(checkpoint, folder / f"{model}.onnx")


def threshold_for(detector, frames: list[np.ndarray], count: int) -> float:
    """Confidence passing about ``count`` candidates per frame, pooled over the frames."""
    nc = len(detector.classes)
    scores = np.concatenate([detector.forward(detector.prepare(f)[0])[0][0][4:4 + nc].max(0) for f in frames])
    return float(np.sort(scores)[-count * len(frames)])


def bench(model: Path, frames: list[np.ndarray], repeats: int) -> dict[str, float]:
    from ultralytics import YOLO

    from naoslam.perception.yolo import LandmarkDetector

    detector = LandmarkDetector(model)
    detector.conf = threshold_for(detector, frames, DETECTIONS_PER_FRAME)
    ultralytics = YOLO(str(model), task="segment")
    blobs = [detector.prepare(f)[0] for f in frames]
    outputs = [detector.forward(b) for b in blobs]

    def own_work(i: int) -> None:  # the front end's own share: preparation and decoding, without the forward pass
        detector.decode(outputs[i], detector.prepare(frames[i])[1])

    runs = {"bare session.run": lambda i: detector.forward(blobs[i]),
            "front end": lambda i: detector(frames[i]),
            "ultralytics predict": lambda i: ultralytics.predict(frames[i], imgsz=[480, 640], conf=detector.conf,
                                                                 verbose=False, retina_masks=True),
            "own work": own_work}
    for run in runs.values():
        run(0)
    times: dict[str, list[float]] = {name: [] for name in runs}
    detections = []
    names = list(runs)
    for repeat in range(repeats):
        # Interleaved in blocks (every frame once per method), the block order rotating each round. Ultralytics'
        # session keeps its threads spinning after a call, which slows whatever runs next; blocks confine that to
        # the first call of a block, and the median ignores it.
        for name in names[repeat % len(names):] + names[:repeat % len(names)]:
            for i in range(len(frames)):
                start = time.perf_counter()
                runs[name](i)
                times[name].append(time.perf_counter() - start)
        detections.extend(len(detector(frame)) for frame in frames)
    out = {name: 1000 * float(np.median(t)) for name, t in times.items()}
    out["detections"] = float(np.mean(detections))
    return out


def main(frame_count: int = 10, models: tuple[str, ...] = ("yolov8s-seg", "yolov8m-seg")) -> None:
    from detector.synth.generate import SynthJob, generate_dataset
    from export.quantize import quantize_int8

    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        data = generate_dataset(folder / "data", SynthJob(frame_count + 20, seed=5), progress=False)
        images = sorted((data / "train" / "images").glob("*.jpg"))
        frames = [cv2.imread(str(p)) for p in images[:frame_count]]
        for model in models:
            fp32 = build_onnx(model, folder, images[frame_count:frame_count + 8])
            int8 = quantize_int8(fp32, folder / f"{model}-int8.onnx", images[frame_count:frame_count + 16])
            for label, path in (("FP32", fp32), ("INT8", int8)):
                r = bench(path, frames, repeats=6)
                print(f"{model} {label}: bare session.run {r['bare session.run']:.1f} ms, front end "
                      f"{r['front end']:.1f} ms ({r['detections']:.1f} detections), Ultralytics predict "
                      f"{r['ultralytics predict']:.1f} ms | front end / bare = "
                      f"{r['front end'] / r['bare session.run']:.3f} (own work {r['own work']:.2f} ms = "
                      f"{100 * r['own work'] / r['bare session.run']:.1f} % of the forward pass), "
                      f"Ultralytics / front end = {r['ultralytics predict'] / r['front end']:.2f}", flush=True)


if __name__ == "__main__":
    count = int(sys.argv[1]) if len(sys.argv) > 1 else 10
    main(count, tuple(sys.argv[2:]) or ("yolov8s-seg", "yolov8m-seg"))
