"""The robot's two-stage front end: pink candidates at full resolution (:mod:`naoslam.perception.candidates`), then one batched
call of a small crop network that names each candidate's pole (or rejects it) and regresses the pole's box in the
crop. No masks: each detection is a box (``Detection.from_box``), which is all range and bearing need. Where the model
file carries a preclassifier (:mod:`naoslam.perception.preclassifier`), it scores every window first and the crop
network looks only at the best of those that pass, at most ``WINDOW_BUDGET`` a frame, whatever the clutter.

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
from naoslam.perception.engines import BatchNetwork
from naoslam.ground import GroundView
from naoslam.perception.model_info import ModelInfo
from naoslam.perception.pole_model import PoleModel, check_options
from naoslam.perception.preclassifier import PRECLASSIFIER_KEY, WINDOW_BUDGET, FrameCost, Preclassifier
from naoslam.shipped import DEFAULT_CONF, resolve_model

#: ``ModelInfo.model`` of a crop network.
CROP_MODEL = "pole-crops"
#: Boxes of one pole found from two candidates overlap at least this much; the lower-scored one is dropped.
NMS_IOU = 0.5
#: Candidates named a pole with at least this probability get a second look, centred on the box the first found.
REFINE_CONF = 0.2
#: A second look whose window overlaps the first one's this much (IoU) would see the same crop: it is not taken.
SAME_WINDOW_IOU = 0.8


def window_iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """IoU of paired windows (N, 4) x0 y0 x1 y1."""
    width = (np.minimum(a[:, 2], b[:, 2]) - np.maximum(a[:, 0], b[:, 0])).clip(0)
    height = (np.minimum(a[:, 3], b[:, 3]) - np.maximum(a[:, 1], b[:, 1])).clip(0)
    inter = width * height
    union = np.prod(a[:, 2:] - a[:, :2], axis=1) + np.prod(b[:, 2:] - b[:, :2], axis=1) - inter
    return inter / np.maximum(union, 1e-9)


def is_crop_model(info: ModelInfo) -> bool:
    """Whether a model's metadata names a crop network."""
    return info.model == CROP_MODEL


class CropDetector(PoleModel):
    """Runs the two-stage front end on BGR or YUYV frames; called like ``LandmarkDetector``.

    ``model``: a crop network's ONNX path (or shipped name); ``session``: its onnxruntime session, if already open.
    ``conf`` None uses the threshold stored in the model, else ``DEFAULT_CONF``. ``engine``: onnxruntime or
    openvino. ``max_candidates``: the most windows the finder keeps a frame (None: its own caps, with the pose and
    without it). ``refine``: give every likely pole a second look centred on its box (more exact boxes; a few more
    crops a frame). ``window_budget``: with the model's preclassifier, the most windows the crop network looks at a
    frame; ``preclassify`` False runs every window through the crop network (as a model without one does).
    """

    #: Boxes are measured in the frame's own pixels, as labels are.
    calibration_width = None
    #: No masks: its detections are compared with labels by box IoU.
    matching = "box"

    def __init__(self, model: Path | str, conf: float | None = None, threads: int | None = None,
                 engine: str = "onnxruntime", max_candidates: int | None = None, refine: bool = True,
                 session=None, window_budget: int = WINDOW_BUDGET, preclassify: bool = True):
        check_options(engine, threads)
        super().__init__(resolve_model(model), threads, session)
        if not is_crop_model(self.info):
            raise ValueError(f"{self.path}: not a two-stage robot model (its metadata names {self.info.model!r}) - "
                             "open it with naoslam.load_detector")
        self.size_wh = (int(self.info.input_hw[1]), int(self.info.input_hw[0]))
        self.finder = CandidateFinder(max_candidates)
        self.conf = (self.stored_conf or DEFAULT_CONF) if conf is None else conf
        if window_budget < 1:
            raise ValueError(f"window budget {window_budget}: let the crop network look at 1 window a frame or more")
        self.engine, self.refine, self.window_budget = engine, refine, window_budget
        self.network = BatchNetwork(self.session, self.path, engine, threads)
        entry = self.info.extra.get(PRECLASSIFIER_KEY)
        #: The model's preclassifier (None: the model has none, or ``preclassify`` is False).
        self.preclassifier = Preclassifier(entry, self.path, threads, engine) if entry and preclassify else None
        #: Candidates of the last frame, and what it cost.
        self.candidates: list = []
        self.cost = FrameCost()

    def forward(self, blob: np.ndarray) -> np.ndarray:
        """The network on (N, 3, H, W) crops: (N, classes + 1 + 4) probabilities and boxes."""
        return self.network(blob)

    def __call__(self, frame: np.ndarray, camera_pose: CameraPose | None = None,
                 view: GroundView | None = None) -> list[Detection]:
        """Detections in one frame, best first; with the camera's pose (or the frame's ground ``view``), only the
        band below the horizon is searched and the ground-plane gate drops what cannot stand on the floor."""
        view = self.view_of(frame.shape[:2], camera_pose, view)
        self.candidates = self.finder(frame, view)
        self.cost = FrameCost(len(self.candidates))
        if not self.candidates:
            return self.gated([], view)
        out, boxes, windows = self.first_look(frame, np.array([c.window for c in self.candidates]))
        if self.refine and len(out):
            out, boxes = self._refined(frame, out, boxes, windows)
        return self.gated(self.decode(out, boxes), view)

    def first_look(self, frame: np.ndarray, windows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The network's answers for the windows the preclassifier passes (all of them without one), their boxes in
        frame pixels and those windows; ``cost`` says how many it looked at."""
        hit_budget = False
        if self.preclassifier is not None:
            small = self.blob(frame, windows, self.preclassifier.size_wh)
            chosen, hit_budget = self.preclassifier.chosen(small, self.window_budget)
            windows = windows[chosen]
        self.cost = FrameCost(self.cost.windows, len(windows), 0, hit_budget)
        out = self.run(frame, windows) if len(windows) else np.zeros((0, len(self.classes) + 5), np.float32)
        return out, self.frame_boxes(out, windows, frame.shape[:2]), windows

    def blob(self, frame: np.ndarray, windows: np.ndarray, size_wh: tuple[int, int] | None = None) -> np.ndarray:
        """The windows of the frame as a network's (N, 3, H, W) input, cut at ``size_wh`` (the crop network's)."""
        return cv2.dnn.blobFromImages(crop_batch(frame, windows, size_wh or self.size_wh), 1.0 / 255.0)

    def run(self, frame: np.ndarray, windows: np.ndarray) -> np.ndarray:
        """The crop network's answers for these windows of the frame (no preclassifier)."""
        return self.forward(self.blob(frame, windows))

    def frame_boxes(self, out: np.ndarray, windows: np.ndarray, frame_hw: tuple[int, int]) -> np.ndarray:
        """The answers' boxes in frame pixels, clipped to the frame."""
        boxes = to_frame(out[:, len(self.classes) + 1:], windows)
        boxes[:, [0, 2]] = boxes[:, [0, 2]].clip(0, frame_hw[1])
        boxes[:, [1, 3]] = boxes[:, [1, 3]].clip(0, frame_hw[0])
        return boxes

    def second_look_windows(self, out: np.ndarray, boxes: np.ndarray, first_windows: np.ndarray,
                            frame_hw: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
        """Which first answers get a second look and the window (N, 4) the finder would draw around each one's box:
        those named a pole with at least ``REFINE_CONF`` with a box of some size, one per pole (of boxes overlapping
        by more than ``NMS_IOU`` the most confident), where that window differs from the first one (IoU under
        ``SAME_WINDOW_IOU``)."""
        scores = out[:, :len(self.classes)].max(axis=1)
        sizes = boxes[:, 2:] - boxes[:, :2]
        likely = np.flatnonzero((scores >= REFINE_CONF) & (sizes > 0).all(axis=1))
        if not likely.size:
            return likely, np.zeros((0, 4))
        kept = cv2.dnn.NMSBoxes(np.concatenate([boxes[likely, :2], sizes[likely]], axis=1).tolist(),
                                scores[likely].astype(float).tolist(), REFINE_CONF, NMS_IOU)
        likely = likely[np.asarray(kept, int).reshape(-1)]
        windows = np.array([window_around_box(tuple(boxes[i]), frame_hw) for i in likely]).reshape(-1, 4)
        moved = window_iou(windows, first_windows[likely]) < SAME_WINDOW_IOU
        return likely[moved], windows[moved]

    def _refined(self, frame: np.ndarray, out: np.ndarray, boxes: np.ndarray,
                 first_windows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """A second look at every candidate the first named a pole with at least ``REFINE_CONF``: the window the
        finder would draw around its box, so the pole stands centred at its own scale. The box is the second look's,
        the class probabilities the mean of both."""
        frame_hw = frame.shape[:2]
        count = len(self.classes)
        again, windows = self.second_look_windows(out, boxes, first_windows, frame_hw)
        if not again.size:
            return out, boxes
        second = self.run(frame, windows)
        self.cost = FrameCost(self.cost.windows, self.cost.looked_at, len(windows), self.cost.hit_budget)
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
