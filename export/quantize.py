"""Static INT8 quantisation with onnxruntime, calibrated on real frames, decode head left in float.

The decode head turns raw distances into box coordinates in pixels (hundreds) next to class scores (0..1) and
mask coefficients; one INT8 scale cannot hold both, so every node of the head after its last feature convolutions
(the DFL, the anchor arithmetic, the concatenations and the final 1x1 predictors) stays float.
"""
from __future__ import annotations

import re
import tempfile
from dataclasses import replace
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np
import onnx
from onnxruntime.quantization import CalibrationDataReader, QuantFormat, QuantType, quantize_static
from onnxruntime.quantization.shape_inference import quant_pre_process

from detector.model_files import read_info, write_metadata
from naoslam.perception.yolo import LandmarkDetector

#: Feature convolutions of the head (cv2/cv3/cv4 stages 0 and 1) and the mask prototype branch: quantised.
_HEAD_FEATURES = re.compile(r"/(cv[234]\.\d+/cv[234]\.\d+\.[01]|proto)/")


class FrameReader(CalibrationDataReader):
    """Feeds network inputs prepared exactly as the front end prepares them."""

    def __init__(self, detector: LandmarkDetector, images: list[Path]):
        self.detector = detector
        self.images = images
        self._iterator: Iterator[dict[str, np.ndarray]] | None = None

    def _inputs(self) -> Iterator[dict[str, np.ndarray]]:
        for path in self.images:
            frame = cv2.imread(str(path))
            if frame is None:
                raise ValueError(f"{path}: cannot be decoded as an image - remove it from the calibration set")
            yield {self.detector.input_name: self.detector.prepare(frame)[0]}

    def get_next(self) -> dict[str, np.ndarray] | None:
        if self._iterator is None:
            self._iterator = self._inputs()
        return next(self._iterator, None)

    def rewind(self) -> None:
        self._iterator = None


def decode_head_nodes(model: onnx.ModelProto) -> list[str]:
    """Names of the nodes of the last (Segment) module that must stay float."""
    modules = [int(m.group(1)) for n in model.graph.node if (m := re.match(r"/model\.(\d+)/", n.name))]
    if not modules:
        raise ValueError("the ONNX graph has no Ultralytics node names (/model.N/...) - export it with `poles export`")
    head = f"/model.{max(modules)}/"
    return [n.name for n in model.graph.node if n.name.startswith(head) and not _HEAD_FEATURES.search(n.name)]


def quantize_int8(fp32: Path, out: Path, images: list[Path], reduce_range: bool = False) -> Path:
    """Write a QDQ INT8 copy of ``fp32`` calibrated on ``images`` (per-channel weights, uint8 activations).

    ``reduce_range`` quantises weights to 7 bits, the safe choice for x86 CPUs without VNNI (e.g. the Nao's Atom).
    """
    if not images:
        raise ValueError("no calibration images - pass --calib-data with a dataset that has training images")
    detector = LandmarkDetector(fp32, classes=None)
    with tempfile.TemporaryDirectory(prefix="poles-int8-") as scratch:
        prepared, quantized = Path(scratch) / "prepared.onnx", Path(scratch) / "int8.onnx"
        quant_pre_process(str(fp32), str(prepared), skip_symbolic_shape=True)
        exclude = decode_head_nodes(onnx.load(str(prepared), load_external_data=False))
        quantize_static(str(prepared), str(quantized), FrameReader(detector, images), quant_format=QuantFormat.QDQ,
                        per_channel=True, reduce_range=reduce_range, activation_type=QuantType.QUInt8,
                        weight_type=QuantType.QInt8, nodes_to_exclude=exclude)
        info = read_info(fp32)
        write_metadata(quantized, replace(info, extra={**info.extra, "precision": "int8"}), out)
    return Path(out)
