"""``poles augment --copies 7`` throughput against a baseline measured in the same run.

Baseline: only decode and re-encode each training image 7 times (the I/O floor of writing 7 copies).
Prints output images per second for both and the ratio.
"""
from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import cv2

from augment.run import augment_dataset
from detector.datasets import load_dataset
from detector.synth.generate import SynthJob, generate_dataset


def main(images: int = 60, copies: int = 7) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        data = generate_dataset(Path(tmp) / "data", SynthJob(images, seed=0), progress=False)
        train = load_dataset(data).split("train")
        start = time.perf_counter()
        for sample in train:
            image = cv2.imread(str(sample.image))
            for _ in range(copies):
                cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 92])
        floor = len(train) * copies / (time.perf_counter() - start)
        for workers in (1, 2):
            start = time.perf_counter()
            augment_dataset(data, Path(tmp) / f"aug{workers}", copies=copies, workers=workers, progress=False)
            rate = len(train) * copies / (time.perf_counter() - start)
            print(f"augment --copies {copies}, {workers} worker(s): {rate:.1f} copies/s; decode+encode floor (1 process): "
                  f"{floor:.1f} copies/s; ratio floor/augment: {floor / rate:.2f}x")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 60)
