"""Inference engines behind ``LandmarkDetector.forward``: onnxruntime (always there) and OpenVINO (optional).

OpenVINO is Intel's runtime; on the two-core benchmark machine it runs the INT8 models faster than onnxruntime with
two threads and as fast with one (``benchmarks/bench_engines.py``), with the same answers. It is imported only when
asked for, so naoslam installs and runs without it.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

ENGINES = ("onnxruntime", "openvino")


class OpenVinoForward:
    """An OpenVINO model compiled once per input shape (the band below the horizon changes height), f32 precision
    hint on float layers so FP32 answers match onnxruntime's."""

    def __init__(self, model: Path | str | object, threads: int | None = None):
        try:
            import openvino as ov  # the optional engine: onnxruntime is the runtime's own
        except ImportError:
            raise ValueError("engine 'openvino' needs the openvino package: pip install openvino") from None
        self.core = ov.Core()
        self.model = self.core.read_model(str(model)) if isinstance(model, (str, Path)) else model
        self.config = {"PERFORMANCE_HINT": "LATENCY", "INFERENCE_PRECISION_HINT": "f32"}
        if threads:
            self.config["INFERENCE_NUM_THREADS"] = threads
        self.compiled: dict[tuple[int, ...], object] = {}

    def __call__(self, blob: np.ndarray) -> list[np.ndarray]:
        shape = tuple(blob.shape)
        if shape not in self.compiled:
            model = self.model.clone()
            model.reshape({model.inputs[0].any_name: list(shape)})
            self.compiled[shape] = self.core.compile_model(model, "CPU", self.config)
        result = self.compiled[shape](blob)
        return [result[i] for i in range(len(result))]
