"""Shared fixtures: a small synthetic dataset rendered once per session, and the optional ../shared folder."""
from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from detector.synth.generate import SynthJob, generate_dataset

SHARED = Path(__file__).resolve().parents[1].parent / "shared"


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
