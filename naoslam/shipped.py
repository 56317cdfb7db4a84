"""The pole model that ships with naoslam: a pole-pretrained YOLOv8n-seg, exported to ONNX (FP32 and INT8).

Its metadata holds the range calibration and the operating confidence threshold (``operating_conf``) chosen on
synthetic validation frames; ``LandmarkDetector()`` with no model uses it at that threshold.
"""
from __future__ import annotations

from pathlib import Path

#: Folder of the shipped ONNX models (package data).
MODELS_DIR = Path(__file__).resolve().parent / "models"
#: Stem of the shipped model's files.
SHIPPED_NAME = "poles-yolov8n-seg"
#: Metadata key of the confidence threshold a model is meant to run at.
OPERATING_CONF_KEY = "operating_conf"


def shipped_path(int8: bool = False) -> Path:
    """Where the shipped ONNX model (FP32, or the INT8 copy) lives in the package."""
    return MODELS_DIR / (f"{SHIPPED_NAME}-int8.onnx" if int8 else f"{SHIPPED_NAME}.onnx")


#: Names that stand for the shipped models wherever a model path is asked for.
SHIPPED_NAMES = {"shipped": False, "shipped-int8": True}


def model_argument(path: Path) -> str:
    """How a command names the model at ``path``: ``shipped`` / ``shipped-int8`` for the shipped ones."""
    named = {shipped_path(int8): name for name, int8 in SHIPPED_NAMES.items()}
    return named.get(Path(path).resolve(), str(path))


def resolve_model(name: str | Path) -> Path:
    """``shipped`` / ``shipped-int8`` as the shipped model's path; any other name as a path."""
    return shipped_model(SHIPPED_NAMES[str(name)]) if str(name) in SHIPPED_NAMES else Path(name)


def shipped_model(int8: bool = False) -> Path:
    """Path of the shipped ONNX model (FP32, or the INT8 copy); an error that says how to get it if it is missing."""
    path = shipped_path(int8)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: the shipped pole model is missing from this installation - reinstall "
                                "nao-poles, or pass your own model exported with `poles export`")
    return path
