"""Inference engines behind ``LandmarkDetector.forward``: onnxruntime (always there) and OpenVINO (optional).

OpenVINO is Intel's runtime; on the two-core benchmark machine it runs the INT8 models faster than onnxruntime with
two threads and as fast with one (``benchmarks/bench_engines.py``), with the same answers. It is imported only when
asked for, so naoslam installs and runs without it.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

ENGINES = ("onnxruntime", "openvino")


def openvino_config(threads: int | None = None, **extra) -> dict:
    """The settings of every OpenVINO compile in the project: latency, and the f32 precision hint. Without the hint
    OpenVINO runs bf16 on a CPU with AVX-512 BF16, whose answers differ from onnxruntime's, and under the Atom's
    instruction-set cap (no bf16) it then fails to compile or crashes; the Atom has no bf16, so every compile that
    stands for the robot says f32. ``extra``: more OpenVINO properties (a profiler's ``PERF_COUNT``)."""
    config = {"PERFORMANCE_HINT": "LATENCY", "INFERENCE_PRECISION_HINT": "f32", **extra}
    if threads:
        config["INFERENCE_NUM_THREADS"] = threads
    return config


class OpenVinoForward:
    """An OpenVINO model compiled once per input shape (the band below the horizon changes height), f32 precision
    hint on float layers so FP32 answers match onnxruntime's."""

    def __init__(self, model: Path | str | bytes | object, threads: int | None = None):
        try:
            import openvino as ov  # the optional engine: onnxruntime is the runtime's own
        except ImportError:
            raise ValueError("engine 'openvino' needs the openvino package: pip install openvino") from None
        self.core = ov.Core()
        self.name = str(model) if isinstance(model, (str, Path)) else "the model"
        if isinstance(model, (str, Path)):
            model = self.core.read_model(str(model))
        self.model = self.core.read_model(model) if isinstance(model, bytes) else model  # bytes: an ONNX graph
        self.threads = threads
        self.compiled: dict[tuple[int, ...], object] = {}

    def __call__(self, blob: np.ndarray) -> list[np.ndarray]:
        shape = tuple(blob.shape)
        if shape not in self.compiled:
            model = self.model.clone()
            model.reshape({model.inputs[0].any_name: list(shape)})
            try:
                self.compiled[shape] = self.core.compile_model(model, "CPU", openvino_config(self.threads))
            except RuntimeError as error:  # the YOLOv8 models at the Atom's SSE4 level: "bad combination"
                why = str(error).strip().splitlines()[-1]
                raise ValueError(f"{self.name}: OpenVINO cannot compile it for this processor ({why}) - run it with "
                                 "engine='onnxruntime', which runs every model on every x86 CPU") from None
        result = self.compiled[shape](blob)
        return [result[i] for i in range(len(result))]


def padded_count(count: int) -> int:
    """The batch a count of crops is run as: up to ``EXACT_BATCHES`` as it is, above that the next multiple of it,
    so OpenVINO compiles a few shapes, not one per count (a padded crop costs as much as a real one)."""
    return count if count <= EXACT_BATCHES else -(-count // EXACT_BATCHES) * EXACT_BATCHES


#: Batches up to this size run as they are; larger ones are padded to a multiple of it.
EXACT_BATCHES = 8


class BatchNetwork:
    """A crop network run on (N, 3, H, W) batches, its first output's rows for the real crops: through onnxruntime
    (``session``) or OpenVINO (compiled from ``model``, a path or ONNX bytes), the batch padded with zeros to
    :func:`padded_count`."""

    def __init__(self, session, model: Path | str | bytes, engine: str = "onnxruntime", threads: int | None = None):
        self.session, self.input_name = session, session.get_inputs()[0].name
        self._openvino = OpenVinoForward(model, threads) if engine == "openvino" else None

    def __call__(self, blob: np.ndarray) -> np.ndarray:
        count = len(blob)
        padded = padded_count(count)
        if padded != count:
            blob = np.concatenate([blob, np.zeros((padded - count,) + blob.shape[1:], blob.dtype)])
        out = self._openvino(blob)[0] if self._openvino is not None else \
            self.session.run(None, {self.input_name: blob})[0]
        return out[:count]
