"""Render rate of ``poles synth`` against the cost floor of writing images: JPEG-encoding same-size frames.

Prints images/s for both, measured in the same run, and their ratio (how many times the floor rendering costs).
"""
from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

from detector.synth.generate import SynthJob, generate_dataset


def main(images: int = 200) -> None:
    rng = np.random.default_rng(0)
    frames = [rng.integers(0, 255, (480, 640, 3), np.uint8) for _ in range(8)]
    start = time.perf_counter()
    for i in range(images):
        cv2.imencode(".jpg", frames[i % len(frames)], [cv2.IMWRITE_JPEG_QUALITY, 90])
    floor = images / (time.perf_counter() - start)
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        generate_dataset(Path(tmp) / "data", SynthJob(images, seed=0), progress=False)
        rate = images / (time.perf_counter() - start)
    print(f"synth render: {rate:.1f} img/s at 640x480 (all cores); JPEG-encode floor: {floor:.1f} img/s; "
          f"ratio floor/render: {floor / rate:.1f}x; 1000 images take about {1000 / rate:.0f} s")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 200)
