"""Fine-tuning benchmark: how good is a user's model after minutes of CPU training, from scratch against from the
shipped pole model?

The "user" dataset is unlike the shipped model's training data: another seed, another camera (1280x960, the
documented 60.97 deg field of view instead of 56.3), rendered rooms only (no real backdrops). Each start trains
YOLOv8n-seg at 640 px, batch 8, for MINUTES[-1] minutes on every core; a snapshot of the weights at each mark in
MINUTES is evaluated on the test split (mask mAP50, precision and recall at 0.5, counted as `poles evaluate` does).
Usage: python benchmarks/bench_finetune.py [MINUTES ...]   (default 5 15)
"""
from __future__ import annotations

import copy
import os
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("YOLO_OFFLINE", "true")


def train_with_snapshots(data: Path, run: Path, weights: Path | None, minutes: list[float]) -> dict[float, Path]:
    """Train for ``minutes[-1]`` minutes; save the (EMA) weights the first time each mark is passed."""
    import torch
    from ultralytics import YOLO

    from detector.training.train import CpuSegmentationTrainer, use_all_cores

    use_all_cores()
    model = YOLO(str(weights) if weights else "yolov8n-seg.yaml", task="segment")
    marks, saved, start = sorted(minutes), {}, time.perf_counter()

    def snapshot(trainer) -> None:
        elapsed = (time.perf_counter() - start) / 60
        for mark in marks:
            if elapsed >= mark and mark not in saved:
                path = run.parent / f"{run.name}-{mark:g}min.pt"
                torch.save({"model": copy.deepcopy(trainer.ema.ema).half(), "train_args": vars(trainer.args)}, path)
                saved[mark] = path

    model.add_callback("on_fit_epoch_end", snapshot)
    model.train(data=str(data / "data.yaml"), epochs=1000, time=marks[-1] / 60, imgsz=640, batch=8, device="cpu",
                amp=False, plots=False, project=str(run.parent), name=run.name, exist_ok=True, cache=True,
                workers=0, trainer=CpuSegmentationTrainer, verbose=False)
    return saved


def main(minutes: list[float]) -> None:
    from detector.evaluation.predictors import TorchPredictor
    from detector.evaluation.run import evaluate
    from detector.synth.generate import SynthJob, generate_dataset
    from detector.model_files import SHIPPED_WEIGHTS

    with tempfile.TemporaryDirectory() as tmp:
        data = generate_dataset(Path(tmp) / "user", SynthJob(200, seed=4242, width=1280, height=960, hfov_deg=60.97),
                                progress=False)
        print(f"{os.cpu_count()} cores; user dataset: 200 frames 1280x960 (140 train / 40 test / 20 valid); "
              f"YOLOv8n-seg at 640, batch 8")
        for start, weights in (("scratch", None), ("shipped", SHIPPED_WEIGHTS)):
            snapshots = train_with_snapshots(data, Path(tmp) / f"run-{start}", weights, minutes)
            for mark in minutes:
                if mark not in snapshots:
                    print(f"{start:>8} after {mark:g} min: no epoch ended after that mark")
                    continue
                m = evaluate(TorchPredictor(snapshots[mark]), data, Path(tmp) / f"eval-{start}-{mark}", "test", 0.5,
                             progress=False)
                print(f"{start:>8} after {mark:g} min: mask mAP50 {m.get('map50', 0):.3f}, precision "
                      f"{m['precision']:.1%}, recall {m['recall']:.1%} (test split, conf 0.5)", flush=True)


if __name__ == "__main__":
    main([float(v) for v in sys.argv[1:]] or [5.0, 15.0])
