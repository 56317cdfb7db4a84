"""Training throughput (images/s) on the CPU: `poles train` settings against plain Ultralytics, n/s/m at 320/640.

Each configuration trains in its own process (thread settings are process-wide) on the same synthetic images, runs
interleaved; the first batch (warm-up, caching) is not timed. Usage: python benchmarks/bench_train.py [IMAGES]
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("YOLO_OFFLINE", "true")

BATCH = 4
VARIANTS = {
    "plain yolo": {},  # Ultralytics' own CPU settings: cpu_count - 1 threads, workers 0, no cache
    "poles train": {"threads": "all", "cache": True},
    "poles train + 1 worker": {"threads": "all", "cache": True, "workers": 1},
}


def one_run(model: str, imgsz: int, variant: str, data: str) -> None:
    """Train one epoch and print the timed images/s as JSON (runs in a child process)."""
    from ultralytics import YOLO

    from detector.training.train import CpuSegmentationTrainer, use_all_cores

    options = VARIANTS[variant]
    if options.get("threads") == "all":
        use_all_cores()
    stamps: list[float] = []
    model_obj = YOLO(f"{model}.yaml")
    model_obj.add_callback("on_train_batch_end", lambda trainer: stamps.append(time.perf_counter()))
    with tempfile.TemporaryDirectory() as project:
        model_obj.train(data=data, epochs=1, imgsz=imgsz, batch=BATCH, device="cpu", amp=False, plots=False,
                        val=False, project=project, name="run", verbose=False, cache=options.get("cache", False),
                        workers=options.get("workers", 0), warmup_epochs=0,
                        trainer=CpuSegmentationTrainer if options else None)
    timed_images = BATCH * (len(stamps) - 1)
    import torch

    print(json.dumps({"images_per_s": timed_images / (stamps[-1] - stamps[0]), "threads": torch.get_num_threads()}))


def main(images: int = 12) -> None:
    from detector.synth.generate import SynthJob, generate_dataset

    with tempfile.TemporaryDirectory() as tmp:
        data = Path(tmp) / "data"
        generate_dataset(data, SynthJob(images * 10 // 7 + 1, seed=3), progress=False)
        results = {}
        for model in ("yolov8n-seg", "yolov8s-seg", "yolov8m-seg"):
            for imgsz in (320, 640):
                for variant in VARIANTS:
                    out = subprocess.run([sys.executable, __file__, "--one", model, str(imgsz), variant,
                                          str(data / "data.yaml")], capture_output=True, text=True, check=True)
                    results[(model, imgsz, variant)] = json.loads(out.stdout.strip().splitlines()[-1])
                base = results[(model, imgsz, "plain yolo")]["images_per_s"]
                line = ", ".join(f"{v} {results[(model, imgsz, v)]['images_per_s']:.2f} img/s "
                                 f"({results[(model, imgsz, v)]['threads']} threads, "
                                 f"x{results[(model, imgsz, v)]['images_per_s'] / base:.2f})" for v in VARIANTS)
                print(f"{model} @ {imgsz}: {line}", flush=True)


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--one":
        one_run(sys.argv[2], int(sys.argv[3]), sys.argv[4], sys.argv[5])
    else:
        main(int(sys.argv[1]) if len(sys.argv) > 1 else 12)
