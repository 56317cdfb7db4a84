"""What every pole model file shares, whichever front end runs it: the ONNX session, the naoslam metadata, the
operating threshold and the range calibration stored in it, and the camera's field of view for the ground view."""
from __future__ import annotations

from pathlib import Path

import onnxruntime as ort

from naoslam.perception.engines import ENGINES
from naoslam.camera import NAO_HFOV_DEG, CameraPose, PinholeCamera
from naoslam.cores import usable_cores
from naoslam.ground import GroundView, ground_gate
from naoslam.measurement import RangeCalibration
from naoslam.perception.model_info import ModelInfo
from naoslam.shipped import OPERATING_CONF_KEY, model_argument, shipped_model


def valid_confidence(conf: float) -> float:
    """``conf`` as a float when it can be a confidence threshold (between 0 and 1), else a ValueError: a threshold
    of 5 would drop every detection and one of -1 keep every candidate box, both without a word."""
    conf = float(conf)
    if not 0.0 < conf < 1.0:
        raise ValueError(f"confidence threshold {conf} must lie between 0 and 1")
    return conf


def session_options(threads: int | None = None) -> ort.SessionOptions:
    """onnxruntime's settings for every network the runtime runs: ``threads`` (None: one per usable core), every graph
    optimisation, and idle worker threads that sleep instead of spinning (the robot's other processes need the cores
    between frames)."""
    options = ort.SessionOptions()
    options.intra_op_num_threads = threads or usable_cores()
    options.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
    options.add_session_config_entry("session.intra_op.allow_spinning", "0")
    return options


def load_session(path: Path | str, threads: int | None = None) -> ort.InferenceSession:
    """An onnxruntime CPU session; a missing or unreadable file raises an error that names it."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such model file - export one with `poles export --weights best.pt`")
    if path.suffix == ".pt":
        raise ValueError(f"{path}: a PyTorch checkpoint; the runtime runs its ONNX export - "
                         f"`poles export --weights {path} --out {path.with_suffix('.onnx')}`")
    try:
        return ort.InferenceSession(str(path), session_options(threads), providers=["CPUExecutionProvider"])
    except Exception as exc:  # onnxruntime raises several private exception types
        raise ValueError(f"{path}: not a readable ONNX model ({str(exc).splitlines()[0][:200]}) - "
                         "re-export it with `poles export`") from None


def check_options(engine: str, threads: int | None) -> None:
    """Refuse an engine naoslam does not have and a thread count below one."""
    if engine not in ENGINES:
        raise ValueError(f"engine {engine!r} is not one of {', '.join(ENGINES)}")
    if threads is not None and threads < 1:
        raise ValueError(f"threads {threads}: give 1 or more, or None for one per core")


def check_classes(model: "PoleModel", classes: tuple[str, ...] | None) -> None:
    """Refuse a model trained on other class names than ``classes`` (None: accept any)."""
    if classes is not None and tuple(model.info.classes) != tuple(classes):
        raise ValueError(f"{model.path}: the model's classes {list(model.info.classes)} are not the pole classes "
                         f"{list(classes)} - train on a dataset whose data.yaml names them in this order")


def shipped_calibration() -> RangeCalibration | None:
    """The range calibration stored in the shipped model. Its colour law is the colour filter's on the Nao's camera,
    the same whatever model runs beside it, so the colour filter ranges with it when it is given no calibration."""
    return PoleModel(shipped_model(int8=True), threads=1).stored_calibration


class PoleModel:
    """A pole model file opened for inference: ``path``, its onnxruntime ``session`` and metadata ``info``.

    Subclasses set ``calibration_width``: the input width whose pixel sizes a calibration must have been measured
    at (None: frame pixels, as on labels).
    """

    calibration_width: int | None = None

    def __init__(self, path: Path, threads: int | None = None, session: ort.InferenceSession | None = None):
        self.path = Path(path)
        self.session = session if session is not None else load_session(self.path, threads)
        self.info = ModelInfo.from_metadata(self.session.get_modelmeta().custom_metadata_map, self.path)
        self.gate_rejections: list[tuple[object, str]] = []
        self.gate_rejected = 0
        calibration = self.stored_calibration  # its camera's field of view holds at any input width
        #: The camera's horizontal field of view for the ground-plane gate: the calibration's, else the Nao's.
        self.hfov_deg = calibration.hfov_deg if calibration is not None else NAO_HFOV_DEG

    @property
    def classes(self) -> tuple[str, ...]:
        return self.info.classes

    @property
    def stored_conf(self) -> float | None:
        """The confidence threshold the model was shipped to run at (``operating_conf`` in its metadata), if any."""
        stored = self.info.extra.get(OPERATING_CONF_KEY)
        return float(stored) if stored is not None else None

    @property
    def stored_calibration(self) -> RangeCalibration | None:
        """The range calibration stored in the model by ``poles calibrate --embed`` (None if there is none)."""
        data = self.info.extra.get("calibration")
        try:
            return RangeCalibration.from_dict(data) if data else None
        except (ValueError, TypeError, KeyError) as error:
            raise ValueError(f"{self.path}: the calibration in the model is not one ({error}) - store a new one "
                             f"with `poles calibrate --embed {model_argument(self.path)}`") from None

    @property
    def calibration(self) -> RangeCalibration | None:
        """The stored calibration, refused (ValueError) when it was measured at another input width than this
        detector runs the model at."""
        stored = self.stored_calibration
        return self.check_calibration(stored) if stored else None

    @property
    def usable_calibration(self) -> RangeCalibration | None:
        """The stored calibration where it holds at this detector's input width, else None: no ranges rather than
        wrong ones."""
        stored = self.stored_calibration
        return stored if stored is not None and self.fits_calibration(stored) else None

    def fits_calibration(self, calibration: RangeCalibration) -> bool:
        """Whether ``calibration``'s laws hold for this detector's masks: measured at its input width, or on labels."""
        return calibration.input_width in (None, self.calibration_width)

    def check_calibration(self, calibration: RangeCalibration) -> RangeCalibration:
        """``calibration``, or ValueError naming the fix when it was measured at another input width."""
        if not self.fits_calibration(calibration):
            measured, width = calibration.input_width, self.calibration_width
            raise ValueError(f"{self.path}: the range calibration was measured at {measured} px input, the model runs "
                             f"at {width} px here, where its masks read other sizes - run it at {measured} "
                             f"(input_width={measured}, --imgsz {measured}) or calibrate at {width} "
                             f"(`poles calibrate --model {model_argument(self.path)} --imgsz {width}`)")
        return calibration

    def view_of(self, frame_hw: tuple[int, int], camera_pose: CameraPose | None,
                view: GroundView | None) -> GroundView | None:
        """The frame's ground view: ``view`` when the caller built it, else one from ``camera_pose`` (None without)."""
        if view is None and camera_pose is not None:
            return self.ground_view(frame_hw, camera_pose)
        return view

    def gated(self, detections: list, view: GroundView | None) -> list:
        """``detections`` the ground-plane gate keeps (all of them without a view); ``gate_rejections`` holds this
        frame's rejected ones with the reason, ``gate_rejected`` counts them over all frames."""
        self.gate_rejections = []
        if view is None:
            return detections
        kept, self.gate_rejections = ground_gate(view, detections)
        self.gate_rejected += len(self.gate_rejections)
        return kept

    def ground_view(self, frame_hw: tuple[int, int], camera_pose: CameraPose) -> GroundView:
        """The floor as this detector's camera sees it in a frame of ``frame_hw`` from ``camera_pose``."""
        return GroundView(PinholeCamera(frame_hw[1], frame_hw[0], self.hfov_deg), camera_pose)

