"""Every OpenVINO compile in the project runs f32, as the Atom does: without the precision hint OpenVINO picks bf16
on a CPU with AVX-512 BF16, and under the Atom's instruction-set cap such a compile fails or crashes."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from naoslam.perception.engines import OpenVinoForward, openvino_config
from naoslam.shipped import robot_path

ROOT = Path(__file__).resolve().parents[1]
#: The project's own Python (a virtual environment or run folders inside the checkout are not its code).
SOURCE_FOLDERS = ("naoslam", "detector", "export", "calibration", "augment", "benchmarks", "tests")


def compile_calls(text: str) -> list[str]:
    """The text of each ``compile_model(...)`` call in a source file, up to its closing bracket."""
    calls = []
    for match in re.finditer(r"compile_model\(", text):
        depth, end = 1, match.end()
        while depth and end < len(text):
            depth += {"(": 1, ")": -1}.get(text[end], 0)
            end += 1
        calls.append(text[match.start():end])
    return calls


def test_every_openvino_compile_in_the_project_takes_the_one_f32_config():
    calls = {path.relative_to(ROOT): compile_calls(path.read_text())
             for folder in SOURCE_FOLDERS for path in (ROOT / folder).rglob("*.py") if path != Path(__file__)}
    found = {path: texts for path, texts in calls.items() if texts}
    assert Path("naoslam/perception/engines.py") in found  # the scan sees the runtime's own compile
    without = [f"{path}: {text}" for path, texts in found.items() for text in texts if "openvino_config(" not in text]
    assert not without, "compile without openvino_config (the f32 hint): " + "; ".join(without)


def test_the_config_asks_for_f32_and_keeps_what_a_caller_adds():
    assert openvino_config()["INFERENCE_PRECISION_HINT"] == "f32"
    config = openvino_config(1, PERF_COUNT=True)
    assert config["INFERENCE_NUM_THREADS"] == 1 and config["PERF_COUNT"] is True
    assert config["INFERENCE_PRECISION_HINT"] == "f32"


def test_the_runtime_s_compiled_robot_network_runs_f32():
    ov = pytest.importorskip("openvino")
    forward = OpenVinoForward(robot_path(), threads=1)
    forward(np.zeros((2, 3, 48, 24), np.float32))
    (compiled,) = forward.compiled.values()
    assert compiled.get_property("INFERENCE_PRECISION_HINT") == ov.Type.f32
