"""Peak memory of ``poles evaluate`` against the number of frames: it must not grow with them.

100 frames are rendered at 1280x960 (a Roboflow export's size class), then a dataset of 100 and one of 1,000 frames
(the same frames under other names, so only the count changes) are each evaluated in a fresh process, and its peak
resident memory is read from the kernel. The ratio 1,000 / 100 is the figure: 1.0 means flat.
Usage: python benchmarks/bench_evaluate_memory.py [MODEL]
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

os.environ.setdefault("YOLO_OFFLINE", "true")

SIZES = (100, 1000)


def dataset_of(source: Path, count: int, out: Path) -> Path:
    """A one-split dataset of ``count`` frames, the rendered ones repeated under new names (hard links)."""
    images, labels = sorted((source / "valid" / "images").glob("*.jpg")), source / "valid" / "labels"
    for folder in ("images", "labels"):
        (out / "valid" / folder).mkdir(parents=True)
    for i in range(count):
        image = images[i % len(images)]
        os.link(image, out / "valid" / "images" / f"{i:05d}.jpg")
        shutil.copyfile(labels / f"{image.stem}.txt", out / "valid" / "labels" / f"{i:05d}.txt")
    shutil.copyfile(source / "data.yaml", out / "data.yaml")
    return out


def peak_mb(data: Path, model: str, out: Path) -> float:
    """Peak resident memory (MiB) of `poles evaluate` on ``data`` in its own process, as the kernel counted it."""
    argv = ["evaluate", "--data", str(data), "--split", "valid", "--model", model, "--out", str(out)]
    code = ("import resource, sys; from detector.cli import main; status = main(%r); "
            "print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss); sys.exit(status)" % argv)
    result = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True)
    return int(result.stdout.strip().splitlines()[-1]) / 1024


def main(model: str) -> None:
    from detector.synth.generate import SynthJob, generate_dataset

    with tempfile.TemporaryDirectory(prefix="bench-memory-") as scratch:
        scratch = Path(scratch)
        rendered = generate_dataset(scratch / "rendered", SynthJob(SIZES[0], seed=11, width=1280, height=960),
                                    progress=False)
        split = scratch / "split"
        subprocess.run([sys.executable, "-m", "detector.cli", "split", "--data", str(rendered), "--out", str(split),
                        "--ratios", "0", "0", "1"], check=True, capture_output=True)
        print(f"poles evaluate --model {model}, 1280x960 frames, peak resident memory of its process")
        print("| frames | peak MiB | / 100 frames |")
        print("| --- | --- | --- |")
        baseline = None
        for count in SIZES:
            peak = peak_mb(dataset_of(split, count, scratch / f"data-{count}"), model, scratch / f"eval-{count}")
            baseline = baseline or peak
            print(f"| {count} | {peak:.0f} | {peak / baseline:.2f} |", flush=True)


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    main(sys.argv[1] if len(sys.argv) > 1 else "shipped-robot")
