"""ONNX front end: frames in, pole detections out (class, confidence, box, full-resolution mask, rotated box).

Pure numpy / OpenCV / onnxruntime, so it runs on the robot. It reproduces Ultralytics' YOLOv8-seg post-processing
(letterbox, class-aware NMS, prototype masks) with one difference on purpose: each mask is sampled straight from the
quarter-resolution prototype logits to full frame resolution inside its box (one bilinear warp), so a thin pole's
width is not quantised to 4 px before the rotated box is measured.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import cv2
import numpy as np

from naoslam.camera import CameraPose
from naoslam.ground import GroundView
from naoslam.landmarks import CLASSES
from naoslam.perception.detections import Detection, mask_centre_column, rotated_box_of_mask
from naoslam.perception.engines import OpenVinoForward
from naoslam.perception.frames import bgr_frame
from naoslam.perception.pole_model import PoleModel, check_classes, check_options, valid_confidence
from naoslam.perception.two_stage import is_crop_model
from naoslam.shipped import DEFAULT_CONF, model_argument, resolve_model

#: Ultralytics' letterbox fill value.
PAD_VALUE = 114


@dataclass(frozen=True)
class Letterbox:
    """How a frame of ``frame_hw`` was resized (to ``content_hw``) and padded (``top``, ``left``) to the input size."""

    frame_hw: tuple[int, int]
    input_hw: tuple[int, int]
    content_hw: tuple[int, int]
    top: int
    left: int

    @classmethod
    def fit(cls, frame_hw: tuple[int, int], input_hw: tuple[int, int]) -> "Letterbox":
        """Ultralytics' centred letterbox (``LetterBox(auto=False)``), rounding exactly as it does."""
        gain = min(input_hw[0] / frame_hw[0], input_hw[1] / frame_hw[1])
        content = (max(round(frame_hw[0] * gain), 1), max(round(frame_hw[1] * gain), 1))
        dh, dw = (input_hw[0] - content[0]) / 2, (input_hw[1] - content[1]) / 2
        return cls(frame_hw, input_hw, content, round(dh - 0.1), round(dw - 0.1))

    def apply(self, frame: np.ndarray) -> np.ndarray:
        """The frame resized and padded to the network input size."""
        if frame.shape[:2] != self.content_hw:
            frame = cv2.resize(frame, self.content_hw[::-1], interpolation=cv2.INTER_LINEAR)
        bottom = self.input_hw[0] - self.content_hw[0] - self.top
        right = self.input_hw[1] - self.content_hw[1] - self.left
        if self.top or bottom or self.left or right:
            frame = cv2.copyMakeBorder(frame, self.top, bottom, self.left, right, cv2.BORDER_CONSTANT,
                                       value=(PAD_VALUE,) * 3)
        return frame

    def boxes_to_frame(self, boxes_xyxy: np.ndarray) -> np.ndarray:
        """Input-space boxes mapped back to the frame and clipped to it."""
        sy, sx = self.content_hw[0] / self.frame_hw[0], self.content_hw[1] / self.frame_hw[1]
        out = (boxes_xyxy - [self.left, self.top, self.left, self.top]) / [sx, sy, sx, sy]
        out[:, [0, 2]] = out[:, [0, 2]].clip(0, self.frame_hw[1])
        out[:, [1, 3]] = out[:, [1, 3]].clip(0, self.frame_hw[0])
        return out

    def content_in_proto(self, proto_hw: tuple[int, int]) -> tuple[int, int, int, int]:
        """The prototype cells (c0, r0, c1, r1; end exclusive) that hold the frame, not the letterbox's padding, as
        Ultralytics' ``scale_masks`` crops them before it interpolates (so a mask at the frame's edge replicates the
        content's last cell instead of blending into the padding)."""
        fy, fx = proto_hw[0] / self.input_hw[0], proto_hw[1] / self.input_hw[1]
        r0, c0 = round(self.top * fy - 0.1), round(self.left * fx - 0.1)
        return (c0, r0, c0 + max(round(self.content_hw[1] * fx), 1), r0 + max(round(self.content_hw[0] * fy), 1))

    def frame_to_proto(self, proto_hw: tuple[int, int]) -> tuple[float, float, float, float]:
        """Affine map (scale_x, offset_x, scale_y, offset_y) from frame pixel index to prototype-map pixel index."""
        fy, fx = proto_hw[0] / self.input_hw[0], proto_hw[1] / self.input_hw[1]
        sy = self.content_hw[0] / self.frame_hw[0] * fy
        sx = self.content_hw[1] / self.frame_hw[1] * fx
        return sx, (self.left + 0.5 * sx / fx) * fx - 0.5, sy, (self.top + 0.5 * sy / fy) * fy - 0.5


class LandmarkDetector(PoleModel):
    """Runs a YOLOv8-seg ONNX pole model on BGR frames (masks, boxes, rotated boxes).

    ``model``: a shipped model's name or an ONNX path (default the accurate model, ``shipped``); the robot's
    two-stage model is opened by :func:`load_detector`. ``conf`` None uses the threshold stored in the model
    (``operating_conf``), else ``DEFAULT_CONF``. ``classes`` is the class list the caller expects (default the six
    pole codes); a model trained on other names is refused. Pass ``classes=None`` to accept any model.
    ``input_width`` runs a model exported with ``--dynamic`` (the shipped ones are) at a smaller scale than it was
    exported at, its height in proportion: fewer pixels for a slower CPU, and poles under about 16 px wide lost
    (docs/camera-pose.md, "Engines and the on-robot budget"). None keeps the model's own input size. ``threads`` None
    runs one inference thread per core; ``iou`` is the NMS overlap (0-1] above which the lower-scored box of a class
    is dropped.
    """

    matching = "mask"

    def __init__(self, model: Path | str = "shipped", conf: float | None = None, iou: float = 0.7,
                 max_det: int = 300, classes: tuple[str, ...] | None = CLASSES, threads: int | None = None,
                 engine: str = "onnxruntime", input_width: int | None = None, session=None):
        check_options(engine, threads)
        if not 0.0 < iou <= 1.0:
            raise ValueError(f"NMS IoU threshold {iou} must lie above 0 and at most 1 (default 0.7)")
        if max_det < 1:
            raise ValueError(f"max_det {max_det}: keep at least 1 detection per frame (default 300)")
        super().__init__(resolve_model(model), threads, session)
        if is_crop_model(self.info):
            raise ValueError(f"{self.path}: a two-stage robot model, not a YOLOv8-seg one - open it with "
                             f"naoslam.load_detector({model_argument(self.path)!r})")
        check_classes(self, classes)
        self._check_signature()
        self.input_hw = self.info.input_hw if input_width is None else self._scaled_input_hw(input_width)
        self.conf = (self.stored_conf or DEFAULT_CONF) if conf is None else valid_confidence(conf)
        self.iou, self.max_det = iou, max_det
        self.input_name = self.session.get_inputs()[0].name
        self.engine = engine
        self._openvino = OpenVinoForward(self.path, threads) if engine == "openvino" else None
        self._letterboxes: dict[tuple[int, int], Letterbox] = {}

    @property
    def calibration_width(self) -> int:
        """Its masks' pixel sizes change with the input width, so a calibration must be measured at it."""
        return self.input_hw[1]

    def _check_signature(self) -> None:
        """Refuse a model whose outputs are not a segmentation head for its classes: (1, 4 + nc + nm, N) predictions
        and (1, nm, h, w) prototypes, nm the number of mask prototypes (32 in YOLOv8-seg, fewer in a robot model)."""
        inputs, outputs = self.session.get_inputs(), self.session.get_outputs()
        shapes = [o.shape for o in outputs]
        nc = len(self.info.classes)
        if len(inputs) != 1 or len(outputs) != 2 or len(shapes[0]) != 3 or len(shapes[1]) != 4 \
                or not isinstance(shapes[1][1], int) or shapes[0][1] != 4 + nc + shapes[1][1]:
            raise ValueError(f"{self.path}: outputs {shapes} are not a YOLOv8 segmentation head for {nc} classes "
                             f"(expected (1, 4 + {nc} + nm, N) and (1, nm, h, w)) - export a *-seg model without NMS")

    @property
    def any_input_size(self) -> bool:
        """True for a model exported with ``--dynamic``: it can run on a band of the frame."""
        return not all(isinstance(side, int) for side in self.session.get_inputs()[0].shape[2:])

    def _scaled_input_hw(self, width: int) -> tuple[int, int]:
        """The model's input size scaled to ``width`` (a multiple of the stride), the height rounded up to one."""
        stride, (height, exported_width) = self.info.stride, self.info.input_hw
        asked = f"input width {width} (--imgsz / input_width)"
        if not self.any_input_size:
            raise ValueError(f"{self.path}: {asked}, but the model takes only {exported_width}x{height} - export it "
                             "with `poles export --dynamic`")
        if width < stride or width % stride:
            raise ValueError(f"{asked}: give a positive multiple of the model's stride {stride}")
        return int(math.ceil(height * width / exported_width / stride) * stride), width

    def letterbox(self, frame_hw: tuple[int, int], input_hw: tuple[int, int] | None = None) -> Letterbox:
        """The (cached) letterbox for frames of this size (into ``input_hw``, default the model's)."""
        key = (frame_hw, input_hw or self.input_hw)
        if key not in self._letterboxes:
            self._letterboxes[key] = Letterbox.fit(*key)
        return self._letterboxes[key]

    def band_input_hw(self, frame_hw: tuple[int, int], band_rows: int) -> tuple[int, int]:
        """Input size for the lowest ``band_rows`` of a frame: the full frame's scale, height rounded up to the stride."""
        gain = min(self.input_hw[0] / frame_hw[0], self.input_hw[1] / frame_hw[1])
        stride = self.info.stride
        return int(math.ceil(band_rows * gain / stride) * stride), self.input_hw[1]

    def prepare(self, frame: np.ndarray, input_hw: tuple[int, int] | None = None) -> tuple[np.ndarray, Letterbox]:
        """The network input tensor (1, 3, H, W) float32 RGB in 0..1 for a BGR (or grey) uint8 frame."""
        frame = bgr_frame(frame)
        box = self.letterbox(frame.shape[:2], input_hw)
        blob = cv2.dnn.blobFromImage(box.apply(frame), 1.0 / 255.0, swapRB=True)
        return blob, box

    def forward(self, blob: np.ndarray) -> list[np.ndarray]:
        """The bare network call: raw (1, 4+nc+32, N) predictions and (1, 32, h, w) prototypes."""
        if self._openvino is not None:
            return self._openvino(blob)
        return self.session.run(None, {self.input_name: blob})

    def __call__(self, frame: np.ndarray, camera_pose: CameraPose | None = None, crop: bool = True,
                 view: GroundView | None = None) -> list[Detection]:
        """Detections in one BGR frame, best first.

        With the camera's ``camera_pose`` (height, pitch, roll; x, y and yaw unused), the ground-plane gate drops
        detections that cannot be a pole standing on the floor (``gate_rejections`` then holds (detection, reason)
        for this frame, ``gate_rejected`` counts them over all frames), and a model exported with ``--dynamic``
        runs only on the band below the horizon, where every pole must be (``crop=False``: the whole frame).
        ``view``: the frame's ground view when the caller has built it already (``FrontEnd`` shares one per frame).
        """
        frame = bgr_frame(frame)
        view = self.view_of(frame.shape[:2], camera_pose, view)
        top = view.band_top() if view is not None and crop and self.any_input_size else 0
        band = frame[top:]
        blob, box = self.prepare(band, self.band_input_hw(frame.shape[:2], band.shape[0]) if top else None)
        detections = self.decode(self.forward(blob), box)
        if top:
            detections = [_shifted(d, top) for d in detections]
        return self.gated(detections, view)

    def decode(self, outputs: list[np.ndarray], box: Letterbox) -> list[Detection]:
        """Confidence filter, class-aware NMS and masks, as Ultralytics' ``non_max_suppression`` + native masks."""
        predictions, protos = outputs[0][0], outputs[1][0]
        nc = len(self.info.classes)
        scores_all = predictions[4:4 + nc]
        best = scores_all.max(axis=0)
        candidates = np.flatnonzero(best > self.conf)
        if candidates.size == 0:
            return []
        scores = best[candidates]
        class_ids = scores_all[:, candidates].argmax(axis=0)
        cx, cy, w, h = predictions[:4, candidates]
        boxes_xyxy = np.stack([cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2], axis=1)
        keep = cv2.dnn.NMSBoxesBatched(np.stack([cx - w / 2, cy - h / 2, w, h], axis=1).astype(np.float64),
                                       scores.astype(np.float64), class_ids.astype(np.int32), self.conf, self.iou)
        keep = np.asarray(keep, dtype=int).reshape(-1)
        keep = keep[np.argsort(-scores[keep], kind="stable")][: self.max_det]
        frame_boxes = box.boxes_to_frame(boxes_xyxy[keep])
        coefficients = predictions[4 + nc:, candidates[keep]].T
        return [self._detection(int(class_ids[k]), float(scores[k]), frame_boxes[i], coefficients[i], protos, box)
                for i, k in enumerate(keep)]

    def _detection(self, class_id: int, score: float, frame_box: np.ndarray, coefficients: np.ndarray,
                   protos: np.ndarray, box: Letterbox) -> Detection:
        mask, origin = _mask_in_box(coefficients, protos, frame_box, box)
        rotated = rotated_box_of_mask(mask, origin)
        centre_column = mask_centre_column(mask, origin) if rotated else float((frame_box[0] + frame_box[2]) / 2)
        return Detection(class_id, self.info.classes[class_id], score, tuple(float(v) for v in frame_box), mask,
                         origin, rotated, centre_column)


def _shifted(detection: Detection, rows: int) -> Detection:
    """A detection found in a band that starts ``rows`` below the frame's top, in frame coordinates."""
    x1, y1, x2, y2 = detection.box
    rotated = detection.rotated_box
    if rotated is not None:
        rotated = replace(rotated, cy=rotated.cy + rows)
    return replace(detection, box=(x1, y1 + rows, x2, y2 + rows),
                   mask_origin=(detection.mask_origin[0], detection.mask_origin[1] + rows), rotated_box=rotated)


def _mask_in_box(coefficients: np.ndarray, protos: np.ndarray, frame_box: np.ndarray,
                 box: Letterbox) -> tuple[np.ndarray, tuple[int, int]]:
    """Full-resolution mask inside the box: prototype logits combined over a window, warped bilinearly, > 0."""
    proto_h, proto_w = protos.shape[1:]
    frame_h, frame_w = box.frame_hw
    x1, y1, x2, y2 = frame_box
    # Pixels whose index lies in [x1, x2) x [y1, y2), as Ultralytics' crop_mask keeps them.
    c0, r0 = int(np.ceil(x1)), int(np.ceil(y1))
    c1, r1 = min(int(np.ceil(x2)), frame_w), min(int(np.ceil(y2)), frame_h)
    if c1 <= c0 or r1 <= r0:
        return np.zeros((0, 0), dtype=bool), (c0, r0)
    sx, ox, sy, oy = box.frame_to_proto((proto_h, proto_w))
    # Prototype window covering the box with one cell of margin, so interpolation at its edge is exact, inside the
    # cells that hold the frame: at the padding's edge the border is replicated from the content.
    content = box.content_in_proto((proto_h, proto_w))
    p0 = max(int(np.floor(c0 * sx + ox)) - 1, content[0]), max(int(np.floor(r0 * sy + oy)) - 1, content[1])
    p1 = min(int(np.ceil((c1 - 1) * sx + ox)) + 2, content[2]), min(int(np.ceil((r1 - 1) * sy + oy)) + 2, content[3])
    window = protos[:, p0[1]:p1[1], p0[0]:p1[0]]
    logits = np.tensordot(coefficients, window, axes=1).astype(np.float32)
    # dst(col, row) = logits(sx * (c0 + col) + ox - p0x, sy * (r0 + row) + oy - p0y)
    warp = np.array([[sx, 0.0, sx * c0 + ox - p0[0]], [0.0, sy, sy * r0 + oy - p0[1]]], dtype=np.float64)
    sampled = cv2.warpAffine(logits, warp, (c1 - c0, r1 - r0), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                             borderMode=cv2.BORDER_REPLICATE)
    return sampled > 0, (c0, r0)
