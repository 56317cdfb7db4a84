"""The robot's two-stage front end: pink candidates at full resolution (:mod:`naoslam.perception.candidates`), then one batched
call of a small crop network that names each candidate's pole (or rejects it) and regresses the pole's box in the
crop. No masks: each detection is a box (``Detection.from_box``), which is all range and bearing need.

The crop network is an ONNX file whose naoslam metadata says ``model: pole-crops`` and gives the crop size as its
input size; its one output holds, per crop, the probabilities of the six landmarks and of no pole, then the box
(x0, y0, x1, y1) normalised to the crop.
"""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from naoslam.camera import CameraPose
from naoslam.perception.candidates import CandidateFinder, window_around_box
from naoslam.perception.crops import crop_batch, to_frame
from naoslam.perception.detections import Detection
from naoslam.perception.engines import OpenVinoForward
from naoslam.ground import GroundView
from naoslam.perception.model_info import ModelInfo
from naoslam.perception.pole_model import PoleModel, check_options
from naoslam.shipped import DEFAULT_CONF, resolve_model

#: ``ModelInfo.model`` of a crop network.
CROP_MODEL = "pole-crops"
#: Boxes of one pole found from two candidates overlap at least this much; the lower-scored one is dropped.
NMS_IOU = 0.5
#: Candidates named a pole with at least this probability get a second look, centred on the box the first found.
REFINE_CONF = 0.2


def is_crop_model(info: ModelInfo) -> bool:
    """Whether a model's metadata names a crop network."""
    return info.model == CROP_MODEL


class CropDetector(PoleModel):
    """Runs the two-stage front end on BGR or YUYV frames; called like ``LandmarkDetector``.

    ``model``: a crop network's ONNX path (or shipped name); ``session``: its onnxruntime session, if already open.
    ``conf`` None uses the threshold stored in the model, else ``DEFAULT_CONF``. ``engine``: onnxruntime or
    openvino. ``max_candidates``: the most windows one frame sends to the network (None: the finder's own caps, with
    the pose and without it). ``refine``: give every likely pole a second look centred on its box (more exact boxes;
    a few more crops a frame).
    """

    #: Boxes are measured in the frame's own pixels, as labels are.
    calibration_width = None
    #: No masks: its detections are compared with labels by box IoU.
    matching = "box"

    def __init__(self, model: Path | str, conf: float | None = None, threads: int | None = None,
                 engine: str = "onnxruntime", max_candidates: int | None = None, refine: bool = True,
                 session=None):
        check_options(engine, threads)
        super().__init__(resolve_model(model), threads, session)
        if not is_crop_model(self.info):
            raise ValueError(f"{self.path}: not a two-stage robot model (its metadata names {self.info.model!r}) - "
                             "open it with naoslam.load_detector")
        self.size_wh = (int(self.info.input_hw[1]), int(self.info.input_hw[0]))
        self.finder = CandidateFinder(max_candidates)
        self.conf = (self.stored_conf or DEFAULT_CONF) if conf is None else conf
        self.engine, self.refine = engine, refine
        self.input_name = self.session.get_inputs()[0].name
        self._openvino = OpenVinoForward(self.path, threads) if engine == "openvino" else None
        #: Candidates of the last frame.
        self.candidates: list = []

    def forward(self, blob: np.ndarray) -> np.ndarray:
        """The network on (N, 3, H, W) crops: (N, classes + 1 + 4) probabilities and boxes. The batch is padded to a
        power of two, so OpenVINO compiles a few shapes (1, 2, 4, ... 32), not one per count."""
        count = len(blob)
        padded = 1 << (count - 1).bit_length()
        if padded != count:
            blob = np.concatenate([blob, np.zeros((padded - count,) + blob.shape[1:], blob.dtype)])
        out = self._openvino(blob)[0] if self._openvino is not None else \
            self.session.run(None, {self.input_name: blob})[0]
        return out[:count]

    def __call__(self, frame: np.ndarray, camera_pose: CameraPose | None = None,
                 view: GroundView | None = None) -> list[Detection]:
        """Detections in one frame, best first; with the camera's pose (or the frame's ground ``view``), only the
        band below the horizon is searched and the ground-plane gate drops what cannot stand on the floor."""
        view = self.view_of(frame.shape[:2], camera_pose, view)
        self.candidates = self.finder(frame, view)
        if not self.candidates:
            return self.gated([], view)
        out, boxes = self.first_look(frame, np.array([c.window for c in self.candidates]))
        if self.refine:
            out, boxes = self._refined(frame, out, boxes)
        return self.gated(self.decode(out, boxes), view)

    def first_look(self, frame: np.ndarray, windows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The network's answers for the candidates' windows and their boxes in frame pixels."""
        out = self.run(frame, windows)
        return out, self.frame_boxes(out, windows, frame.shape[:2])

    def run(self, frame: np.ndarray, windows: np.ndarray) -> np.ndarray:
        """The network's answers for these windows of the frame."""
        crops = crop_batch(frame, [tuple(w) for w in windows], self.size_wh)
        return self.forward(cv2.dnn.blobFromImages(crops, 1.0 / 255.0))

    def frame_boxes(self, out: np.ndarray, windows: np.ndarray, frame_hw: tuple[int, int]) -> np.ndarray:
        """The answers' boxes in frame pixels, clipped to the frame."""
        boxes = to_frame(out[:, len(self.classes) + 1:], windows)
        boxes[:, [0, 2]] = boxes[:, [0, 2]].clip(0, frame_hw[1])
        boxes[:, [1, 3]] = boxes[:, [1, 3]].clip(0, frame_hw[0])
        return boxes

    def second_look_windows(self, out: np.ndarray, boxes: np.ndarray,
                            frame_hw: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
        """Which first answers get a second look (indices: named a pole with at least ``REFINE_CONF``, a box of some
        size) and the window (N, 4) the finder would draw around each one's box."""
        likely = out[:, :len(self.classes)].max(axis=1) >= REFINE_CONF
        again = np.flatnonzero(likely & (boxes[:, 2:] > boxes[:, :2]).all(axis=1))
        windows = np.array([window_around_box(tuple(boxes[i]), frame_hw) for i in again]).reshape(-1, 4)
        return again, windows

    def _refined(self, frame: np.ndarray, out: np.ndarray, boxes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """A second look at every candidate the first named a pole with at least ``REFINE_CONF``: the window the
        finder would draw around its box, so the pole stands centred at its own scale. The box is the second look's,
        the class probabilities the mean of both."""
        frame_hw = frame.shape[:2]
        count = len(self.classes)
        again, windows = self.second_look_windows(out, boxes, frame_hw)
        if not again.size:
            return out, boxes
        second = self.run(frame, windows)
        out, boxes = out.copy(), boxes.copy()
        out[again, :count + 1] = (out[again, :count + 1] + second[:, :count + 1]) / 2
        boxes[again] = self.frame_boxes(second, windows, frame_hw)
        return out, boxes

    def decode(self, out: np.ndarray, boxes: np.ndarray) -> list[Detection]:
        """Confident answers as detections, one per pole (overlapping boxes: the best kept), best first."""
        count = len(self.classes)
        scores = out[:, :count].max(axis=1)
        sizes = boxes[:, 2:] - boxes[:, :2]
        keep = np.flatnonzero((scores >= self.conf) & (sizes > 0).all(axis=1))
        if not keep.size:
            return []
        chosen = cv2.dnn.NMSBoxes(np.concatenate([boxes[keep, :2], sizes[keep]], axis=1).tolist(),
                                  scores[keep].astype(float).tolist(), self.conf, NMS_IOU)
        chosen = sorted(keep[np.asarray(chosen, int).reshape(-1)], key=lambda i: -scores[i])
        class_ids = out[:, :count].argmax(axis=1)
        return [Detection.from_box(self.classes[class_ids[i]], float(scores[i]), tuple(boxes[i]),
                                   class_id=int(class_ids[i])) for i in chosen]
