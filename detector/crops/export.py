"""The crop network as the robot runs it: ONNX with a batch of any size, softmax inside, the naoslam metadata that
``naoslam.load_detector`` reads (``model: pole-crops``, the crop size as the input size, the operating threshold),
and a check that onnxruntime gives PyTorch's answers on real crops before the file is written."""
from __future__ import annotations

import tempfile
import warnings
from pathlib import Path

import numpy as np
import onnxruntime as ort
import torch

from detector.crops.network import DeployedCropNet, PoleCropNet
from detector.model_files import write_metadata
from naoslam.perception.two_stage import CROP_MODEL
from naoslam.landmarks import CLASSES
from naoslam.perception.model_info import ModelInfo
from naoslam.shipped import OPERATING_CONF_KEY

#: Largest difference allowed between onnxruntime's and PyTorch's outputs on the check crops.
AGREEMENT = 1e-4


def export_crop_network(network: PoleCropNet, out: Path, check_crops: np.ndarray, conf: float,
                        extra: dict | None = None) -> float:
    """Write ``network`` to ``out`` (atomically) after checking it on ``check_crops`` (N, H, W, 3 BGR uint8);
    returns the largest output difference. ValueError when onnxruntime and PyTorch disagree."""
    deployed = DeployedCropNet(network.eval()).eval()
    width, height = network.size_wh
    with tempfile.TemporaryDirectory() as folder:
        bare = Path(folder) / "bare.onnx"
        with warnings.catch_warnings():  # the TorchScript exporter: all a graph of plain layers needs, no onnxscript
            warnings.simplefilter("ignore", DeprecationWarning)
            torch.onnx.export(deployed, torch.zeros(1, 3, height, width), str(bare), input_names=["crops"],
                              output_names=["poles"], dynamic_axes={"crops": {0: "n"}, "poles": {0: "n"}},
                              opset_version=17, dynamo=False)
        difference = _difference(deployed, bare, check_crops)
        if difference > AGREEMENT:
            raise ValueError(f"{out}: the ONNX crop network differs from PyTorch by {difference:.2g} (at most "
                             f"{AGREEMENT:g}) - not written")
        info = ModelInfo(CLASSES, (height, width), 1, CROP_MODEL, {OPERATING_CONF_KEY: conf, **(extra or {})})
        write_metadata(bare, info, out)
    return difference


def _difference(deployed: DeployedCropNet, path: Path, crops: np.ndarray) -> float:
    """Largest absolute difference of onnxruntime's outputs from PyTorch's on the crops."""
    blob = crops.transpose(0, 3, 1, 2).astype(np.float32) / 255.0
    session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    onnx_out = session.run(None, {"crops": blob})[0]
    with torch.no_grad():
        torch_out = deployed(torch.from_numpy(blob)).numpy()
    return float(np.abs(onnx_out - torch_out).max()) if len(blob) else 0.0
