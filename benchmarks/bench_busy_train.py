"""Training throughput on a busy CPU: plain Ultralytics against `poles train` on every core with OpenMP's default
wait, with a passive wait, with a short spin, and with the thread tuner, each idle, beside one single-threaded CPU
hog, and beside a multi-threaded load, in one run.

Each measurement trains YOLOv8n-seg at 320 px, batch 16, in its own process for SECONDS seconds after the first
batch and reports images/s; the load runs at the same priority. Ratios are against plain Ultralytics under the same
load. libgomp (torch's OpenMP) reads its wait settings once, when torch loads, so each variant's environment is set
before its process starts. Usage: python benchmarks/bench_busy_train.py [SECONDS] [VARIANT ...]
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

BATCH, IMGSZ = 16, 320
#: Variant name: extra environment of its process.
VARIANTS = {
    "plain yolo": {},
    "poles: all cores": {"GOMP_SPINCOUNT": "300000"},  # libgomp's default spin, stated so the row cannot drift
    "poles: passive wait": {"OMP_WAIT_POLICY": "PASSIVE"},
    "poles: short spin": {"GOMP_SPINCOUNT": "10000"},
    "poles: tuner": {},
}
HOG = "while True: pass"
MATMUL = ("import os; os.environ['OMP_NUM_THREADS'] = '2'; import numpy as np; a = np.random.rand(600, 600)\n"
          "while True: a = a @ a; a /= np.abs(a).max()")
LOADS = {"idle": [], "one hog": [HOG], "multi-threaded load": [MATMUL, MATMUL]}


class Enough(Exception):
    """Raised from a callback once the time budget is spent."""


def one_run(variant: str, data: str, seconds: float) -> None:
    """Train until ``seconds`` have passed after the first batch; print images/s and the final thread count."""
    import torch
    from ultralytics import YOLO

    from detector.training.cpu_threads import ThreadTuner
    from detector.training.train import CpuSegmentationTrainer, use_all_cores

    model = YOLO("yolov8n-seg.yaml")
    stamps: list[float] = []

    def stop_when_done(trainer) -> None:
        stamps.append(time.perf_counter())
        if stamps[-1] - stamps[0] > seconds:
            raise Enough

    if variant != "plain yolo":
        threads = use_all_cores()
        if variant == "poles: tuner":
            model.add_callback("on_train_batch_end", ThreadTuner(threads, probe_every=12))
    model.add_callback("on_train_batch_end", stop_when_done)
    with tempfile.TemporaryDirectory() as project:
        try:
            model.train(data=data, epochs=50, imgsz=IMGSZ, batch=BATCH, device="cpu", amp=False, plots=False,
                        val=False, project=project, name="run", verbose=False, cache=variant != "plain yolo",
                        workers=0, warmup_epochs=0,
                        trainer=CpuSegmentationTrainer if variant != "plain yolo" else None)
        except Enough:
            pass
    rate = BATCH * (len(stamps) - 1) / (stamps[-1] - stamps[0])
    print(json.dumps({"images_per_s": rate, "threads": torch.get_num_threads()}))


def main(seconds: float = 60.0, variants: tuple[str, ...] = tuple(VARIANTS)) -> None:
    from detector.synth.generate import SynthJob, generate_dataset

    with tempfile.TemporaryDirectory() as tmp:
        data = Path(tmp) / "data"
        generate_dataset(data, SynthJob(230, seed=3), progress=False)
        print(f"{os.cpu_count()} cores; YOLOv8n-seg @ {IMGSZ}, batch {BATCH}, {seconds:.0f} s per measurement")
        for load, scripts in LOADS.items():
            hogs = [subprocess.Popen([sys.executable, "-c", script]) for script in scripts]
            try:
                rates = {}
                for variant in ("plain yolo", *(v for v in variants if v != "plain yolo")):
                    out = subprocess.run([sys.executable, __file__, "--one", variant, str(data / "data.yaml"),
                                          str(seconds)], capture_output=True, text=True, check=True,
                                         env={**os.environ, **VARIANTS[variant]})
                    rates[variant] = json.loads(out.stdout.strip().splitlines()[-1])
            finally:
                for hog in hogs:
                    hog.kill()
            base = rates["plain yolo"]["images_per_s"]
            print(f"{load:>20}: " + ", ".join(f"{v} {r['images_per_s']:.2f} img/s (x{r['images_per_s'] / base:.2f}, "
                                               f"{r['threads']} threads at the end)" for v, r in rates.items()),
                  flush=True)


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--one":
        one_run(sys.argv[2], sys.argv[3], float(sys.argv[4]))
    else:
        main(float(sys.argv[1]) if len(sys.argv) > 1 else 60.0, tuple(sys.argv[2:]) or tuple(VARIANTS))
