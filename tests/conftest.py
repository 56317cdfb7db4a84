"""Shared fixtures and paths: a small synthetic dataset rendered once per session, the repository root and the
optional ../shared folder."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys


def _share_the_cores_among_test_workers() -> None:
    """Under pytest-xdist, give each worker its own share of the cores (one each on two cores), so that a worker
    running on every core (torch, onnxruntime, the renderer's processes) never oversubscribes the other's."""
    workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))
    worker = os.environ.get("PYTEST_XDIST_WORKER", "")
    if workers < 2 or not worker.startswith("gw") or not hasattr(os, "sched_setaffinity"):
        return
    cores = sorted(os.sched_getaffinity(0))
    share = len(cores) // workers
    if share >= 1:
        index = int(worker[2:]) % workers
        os.sched_setaffinity(0, cores[index * share:(index + 1) * share])


_share_the_cores_among_test_workers()  # before torch, onnxruntime or OpenCV choose their thread counts
from pathlib import Path

import cv2
import numpy as np
import pytest

from detector.synth.generate import SynthJob, generate_dataset
from detector.synth.render import render_scene
from detector.synth.scene import calibration_scene
from naoslam.camera import PinholeCamera

REPOSITORY = Path(__file__).resolve().parents[1]
SHARED = REPOSITORY.parent / "shared"


def rendered_pole(code: str, range_m: float, angle_deg: float, seed: int):
    """One pole rendered by a 640x480 Nao camera: the BGR uint8 frame and the render (with the pole's mask)."""
    scene = calibration_scene(np.random.default_rng(seed), PinholeCamera(640, 480), code, range_m=range_m,
                              angle_deg=angle_deg)
    frame = render_scene(scene)
    return cv2.cvtColor((frame.image * 255 + 0.5).astype(np.uint8), cv2.COLOR_RGB2BGR), frame


#: Modules a runtime process must never load: the training side and its libraries.
TRAINING_SIDE = ("torch", "ultralytics", "albumentations", "detector", "export")


def assert_runs_without_training_side(statement: str) -> None:
    """Run ``statement`` (after ``import numpy as np``) in a fresh Python and fail if it loaded the training side."""
    code = (f"import sys, numpy as np; {statement}; "
            f"bad = [m for m in {TRAINING_SIDE!r} if m in sys.modules]; print(bad); sys.exit(1 if bad else 0)")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr


@pytest.fixture(scope="session")
def synth_dataset(tmp_path_factory) -> Path:
    """24 synthetic 320x240 frames (read-only: copy before changing)."""
    return generate_dataset(tmp_path_factory.mktemp("synth") / "data", SynthJob(24, seed=7, width=320, height=240),
                            workers=1, progress=False)


@pytest.fixture
def dataset_copy(synth_dataset, tmp_path) -> Path:
    """A private copy of the synthetic dataset that a test may damage."""
    return Path(shutil.copytree(synth_dataset, tmp_path / "copy"))


@pytest.fixture
def real_poles() -> Path:
    path = SHARED / "real-poles"
    if not (path / "data.yaml").is_file():
        pytest.skip("../shared/real-poles is not on this machine")
    return path


@pytest.fixture(scope="session")
def tiny_run(synth_dataset, tmp_path_factory) -> Path:
    """yolov8n-seg trained for one epoch at 64 px on the synthetic dataset (run folder)."""
    from detector.training.train import TrainSettings, train_model

    settings = TrainSettings(model="yolov8n-seg", epochs=1, imgsz=64, batch=8, workers=0)
    return train_model(synth_dataset, tmp_path_factory.mktemp("train") / "run", settings)


@pytest.fixture(scope="session")
def tiny_weights(tiny_run, synth_dataset) -> Path:
    """The tiny run's checkpoint with batch-norm statistics re-estimated, so its detections depend on the frame."""
    from detector.training.train import recalibrate_batchnorm

    images = sorted((synth_dataset / "train" / "images").glob("*.jpg"))[:16]
    return recalibrate_batchnorm(tiny_run / "weights" / "last.pt", images, (96, 128), tiny_run / "recalibrated.pt")


@pytest.fixture(scope="session")
def tiny_onnx(tiny_weights) -> Path:
    """The tiny model exported at 128x96 (the 320x240 frames scale without padding)."""
    from export.onnx_export import export_onnx

    return export_onnx(tiny_weights, tiny_weights.with_name("tiny.onnx"), (96, 128))
