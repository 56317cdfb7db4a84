"""One way to open any pole detector by name or file: the YOLOv8-seg front end, the two-stage robot front end or the
colour filter."""
from __future__ import annotations

from pathlib import Path

from naoslam.landmarks import CLASSES
from naoslam.perception.colour_filter import ColourFilter
from naoslam.perception.interface import PoleDetector
from naoslam.perception.model_info import ModelInfo
from naoslam.perception.pole_model import check_classes, check_options, load_session, valid_confidence
from naoslam.perception.two_stage import CropDetector, is_crop_model
from naoslam.perception.yolo import LandmarkDetector
from naoslam.shipped import COLOUR_FILTER, resolve_model


def load_detector(model: Path | str | None = "shipped", conf: float | None = None, threads: int | None = None,
                  engine: str = "onnxruntime", input_width: int | None = None,
                  classes: tuple[str, ...] | None = CLASSES) -> PoleDetector:
    """The detector for a model: ``shipped`` (also for None), ``shipped-int8``, ``shipped-robot``, ``colour-filter``
    or an ONNX path. A YOLOv8-seg model gives a ``LandmarkDetector``, a two-stage robot model a ``CropDetector``, the
    name ``colour-filter`` the thesis's ``ColourFilter``; all are called the same way (a ``PoleDetector``: frame and
    optional camera pose or ground view in, ``Detection`` objects out)."""
    check_options(engine, threads)
    if model == COLOUR_FILTER:
        if input_width is not None:
            raise ValueError(f"the colour filter reads the frame's own pixels - leave out the input width "
                             f"({input_width})")
        return ColourFilter()
    path = resolve_model("shipped" if model is None else model)
    session = load_session(path, threads)
    info = ModelInfo.from_metadata(session.get_modelmeta().custom_metadata_map, path)
    if not is_crop_model(info):
        return LandmarkDetector(path, conf=conf, threads=threads, engine=engine, input_width=input_width,
                                classes=classes, session=session)
    if input_width is not None:
        raise ValueError(f"{path}: a two-stage robot model runs on the frame's own pixels - leave out the input "
                         f"width ({input_width})")
    detector = CropDetector(path, conf=None if conf is None else valid_confidence(conf), threads=threads,
                            engine=engine, session=session)
    check_classes(detector, classes)
    return detector
