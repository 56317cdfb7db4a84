"""The pole models that ship with naoslam, each an ONNX file whose metadata holds its range calibration and the
confidence threshold it runs at (``operating_conf``).

- the accurate model (``shipped``, and its INT8 copy ``shipped-int8``): YOLOv8n-seg at 640 px, for offline analysis,
  pre-labelling and machines with a vector unit;
- the robot model (``shipped-robot``): the two-stage front end's crop network (pink candidates at full resolution,
  then a small network per candidate; ``naoslam.perception.two_stage``), for the Nao's Atom.

``load_detector("shipped")`` opens the accurate one, ``load_detector("shipped-robot")`` the robot one,
``load_detector("colour-filter")`` the thesis's colour filter.
"""
from __future__ import annotations

from pathlib import Path

#: Folder of the shipped ONNX models (package data).
MODELS_DIR = Path(__file__).resolve().parent / "models"
#: Stem of the accurate model's files.
SHIPPED_NAME = "poles-yolov8n-seg"
#: Stem of the robot model's file.
ROBOT_NAME = "poles-robot"
#: Metadata key of the confidence threshold a model is meant to run at.
OPERATING_CONF_KEY = "operating_conf"
#: The threshold of a model that stores none (Ultralytics' predict default), in every command and on the robot.
DEFAULT_CONF = 0.25
#: Names that stand for the shipped models wherever a model path is asked for, and their files.
SHIPPED_FILES = {"shipped": f"{SHIPPED_NAME}.onnx", "shipped-int8": f"{SHIPPED_NAME}-int8.onnx",
                 "shipped-robot": f"{ROBOT_NAME}.onnx"}
#: The name that stands for the colour filter wherever a model is asked for.
COLOUR_FILTER = "colour-filter"


def shipped_path(int8: bool = False) -> Path:
    """Where the accurate model (FP32, or the INT8 copy) lives in the package."""
    return MODELS_DIR / SHIPPED_FILES["shipped-int8" if int8 else "shipped"]


def robot_path() -> Path:
    """Where the robot model lives in the package."""
    return MODELS_DIR / SHIPPED_FILES["shipped-robot"]


def model_argument(path: Path) -> str:
    """How a command names the model at ``path``: ``shipped``, ``shipped-int8`` or ``shipped-robot`` for the
    shipped ones."""
    named = {(MODELS_DIR / file).resolve(): name for name, file in SHIPPED_FILES.items()}
    return named.get(Path(path).resolve(), str(path))


def resolve_model(name: str | Path) -> Path:
    """A shipped model's name as its path; any other name as a path."""
    return _installed(MODELS_DIR / SHIPPED_FILES[str(name)]) if str(name) in SHIPPED_FILES else Path(name)


def shipped_model(int8: bool = False) -> Path:
    """Path of the accurate model (FP32, or the INT8 copy); an error that says how to get it if it is missing."""
    return _installed(shipped_path(int8))


def _installed(path: Path) -> Path:
    if not path.is_file():
        raise FileNotFoundError(f"{path}: the shipped pole model is missing from this installation - reinstall "
                                "nao-poles, or pass your own model exported with `poles export`")
    return path
