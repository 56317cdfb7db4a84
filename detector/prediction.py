"""``poles predict``: run a pole model on new frames.

Pre-labelling writes a dataset Roboflow uploads as pre-annotations (YOLOv8 or COCO layout, simplified polygons,
class names, an empty label for a frame with nothing), so labelling the next batch is correcting, not drawing.
An overlay video draws each frame's masks, class, confidence, range and bearing, with a contact sheet beside it.
"""
from __future__ import annotations

import json
import os
import shutil
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from detector.console import show_progress
from detector.datasets.check import MIN_FRAME_SIDE
from detector.datasets.io import DATASET, IMAGE_SUFFIXES, DatasetWriter, require_decodable
from detector.datasets.model import Instance
from detector.datasets.polygons import mask_to_polygon
from detector.outputs import check_output_file, output_folder
from detector.preview import CLASS_BGR, contact_sheet, draw_label
from naoslam.perception.detections import Detection
from naoslam.perception.loading import load_detector
from naoslam.landmarks import CLASSES
from naoslam.front_end import FrontEnd
from naoslam.measurement import Measurement

#: Outline simplification for pre-labels (px): few vertices to correct, still within a pixel of the mask.
PRELABEL_EPSILON_PX = 1.0
#: Frame rate of a video made from a folder of frames (the Nao's top camera).
FOLDER_FPS = 15.0
#: Tiles in the contact sheet beside a video.
SHEET_TILES = 12
#: The sheet's grid: tiles wide enough that the drawn labels stay readable.
SHEET_COLUMNS, SHEET_TILE_WIDTH = 3, 640


def frames_in(source: Path, subfolders: bool = False) \
        -> tuple[int, float, Iterator[tuple[str, np.ndarray, Path | None]]]:
    """(frame count, frames per second, (name, BGR frame, its file or None for a video's) in order) of a folder of
    images or a video file. With ``subfolders`` a folder's subfolders are read too (``walk1/0001.jpg`` is named
    ``walk1_0001.jpg``). A folder's frames are all checked to decode first, so a bad one is refused before any model
    runs."""
    source = Path(source)
    if source.is_dir():
        named = _images_by_name(source, subfolders)
        require_decodable(list(named.values()))
        return len(named), FOLDER_FPS, ((name, cv2.imread(str(p), cv2.IMREAD_COLOR), p) for name, p in named.items())
    capture = cv2.VideoCapture(str(source))
    count = int(capture.get(cv2.CAP_PROP_FRAME_COUNT)) if capture.isOpened() else 0
    if count <= 0:
        raise ValueError(f"{source}: not a readable video or folder of frames")
    fps = capture.get(cv2.CAP_PROP_FPS) or FOLDER_FPS

    def decode() -> Iterator[tuple[str, np.ndarray]]:
        index = 0
        while True:
            ok, frame = capture.read()
            if not ok:
                break
            yield f"{source.stem}_{index:05d}.jpg", frame, None
            index += 1
        capture.release()

    return count, fps, decode()


def _images_by_name(folder: Path, subfolders: bool) -> dict[str, Path]:
    """A folder's images (hidden files and folders left out), by the name each gets in a flat output: its path
    below ``folder`` joined by ``_``. Two images that would get one name are refused."""
    paths = sorted(path for path in folder.glob("**/*" if subfolders else "*")
                   if path.is_file() and path.suffix.lower() in IMAGE_SUFFIXES
                   and not any(part.startswith(".") for part in path.relative_to(folder).parts))
    if not paths:
        raise ValueError(f"{folder}: no images ({', '.join(sorted(IMAGE_SUFFIXES))}) in it")
    named: dict[str, Path] = {}
    for path in paths:
        name = "_".join(path.relative_to(folder).parts)
        if name in named:
            raise ValueError(f"{named[name]} and {path} would both be named {name} - rename one; nothing was written")
        named[name] = path
    return named


def detections_to_instances(detections: list[Detection], frame_hw: tuple[int, int]) -> list[Instance]:
    """Each detection's mask as a simplified, normalised outline (detections without an outline are skipped)."""
    h, w = frame_hw
    instances = []
    for d in detections:
        polygon = mask_to_polygon(d.full_mask((h, w)), epsilon_px=PRELABEL_EPSILON_PX)
        if polygon is not None:
            instances.append(Instance(d.name, polygon / np.array([w, h], np.float64)))
    return instances


@dataclass(frozen=True)
class Prelabels:
    """What ``poles predict --images`` wrote: frames, poles found, frames without one, at which threshold, where."""

    frames: int
    poles: int
    empty: int
    conf: float
    out: Path


@dataclass(frozen=True)
class OverlayVideo:
    """What ``poles predict --video`` wrote: its frames, the video and its contact sheet, and whether ranges were
    drawn (only where the model's calibration holds at the input width it ran at)."""

    frames: int
    fps: float
    video: Path
    sheet: Path
    conf: float
    ranges: bool


def prelabel(images: Path, out: Path, model: Path | None = None, conf: float | None = None, fmt: str = "yolov8",
             force: bool = False, progress: bool = True) -> Prelabels:
    """Write pre-annotations for every frame in ``images`` to ``out`` (all in the train split); returns counts.

    Frames stream from the source through the model into the writer, one at a time, so a long recording needs the
    memory of one frame, and a bad frame or an existing ``out`` is refused before the model runs."""
    if fmt not in ("yolov8", "coco"):
        raise ValueError(f"--format {fmt!r}: choose yolov8 or coco")
    detector = load_detector(model, conf=conf)
    count, _, frames = frames_in(images, subfolders=True)
    poles_per_frame = []

    def labelled() -> Iterator[tuple[str, np.ndarray, Path | None, list[Instance]]]:
        for name, frame, path in show_progress(frames, "pre-labelling", "img", total=count, enabled=progress):
            instances = detections_to_instances(detector(frame), frame.shape[:2])
            poles_per_frame.append(len(instances))
            yield name, frame, path, instances

    write_prelabels(out, labelled(), fmt, force, Path(images).resolve())
    return Prelabels(len(poles_per_frame), sum(poles_per_frame), poles_per_frame.count(0), detector.conf,
                     Path(out).resolve())


#: What a pre-labelling writer is handed: each frame's name, pixels, its file (None for a video's) and outlines.
Labelled = Iterable[tuple[str, np.ndarray, Path | None, list[Instance]]]


def write_prelabels(out: Path, labelled: Labelled, fmt: str, force: bool, protect: Path,
                    beside: Callable[[Path], None] | None = None) -> None:
    """Write pre-labelled frames as a Roboflow upload (``yolov8`` or ``coco`` layout, all in the train split) into
    ``out``, atomically; ``beside`` writes more files into the folder before it is moved into place."""
    if fmt == "yolov8":
        with DatasetWriter(out, force=force, protect=(protect,)) as writer:
            for name, frame, path, instances in labelled:
                writer.add("train", name, path or jpeg_bytes(frame), instances)
            if beside:
                beside(writer.tmp)
    else:
        _write_coco(out, labelled, force, protect, beside)


def jpeg_bytes(frame: np.ndarray) -> bytes:
    """A frame as JPEG bytes at quality 95 (a video's frames, written into a dataset)."""
    return cv2.imencode(".jpg", frame, [cv2.IMWRITE_JPEG_QUALITY, 95])[1].tobytes()


def _write_coco(out: Path, labelled: Labelled, force: bool, protect: Path,
                beside: Callable[[Path], None] | None = None) -> None:
    """Roboflow's COCO layout: ``train/`` holding the images (copied from their files when the frames came from a
    folder) and ``_annotations.coco.json`` (pixel polygons)."""
    categories = [{"id": i, "name": code, "supercategory": "poles"} for i, code in enumerate(CLASSES)]
    images, annotations = [], []
    with output_folder(out, force, (protect,), DATASET) as tmp:
        (tmp / "train").mkdir()
        for index, (name, frame, path, instances) in enumerate(labelled):
            target = tmp / "train" / name
            shutil.copyfile(path, target) if path else target.write_bytes(jpeg_bytes(frame))
            h, w = frame.shape[:2]
            images.append({"id": index, "file_name": name, "width": w, "height": h})
            for inst in instances:
                pixels = inst.pixels(w, h)
                (x0, y0), (x1, y1) = pixels.min(axis=0), pixels.max(axis=0)
                annotations.append({"id": len(annotations), "image_id": index, "category_id": CLASSES.index(inst.cls),
                                    "segmentation": [np.round(pixels.reshape(-1), 2).tolist()], "iscrowd": 0,
                                    "bbox": [round(float(v), 2) for v in (x0, y0, x1 - x0, y1 - y0)],
                                    "area": round(float((x1 - x0) * (y1 - y0)), 2)})
        (tmp / "train" / "_annotations.coco.json").write_text(json.dumps(
            {"images": images, "annotations": annotations, "categories": categories}))
        if beside:
            beside(tmp)


def overlay_video(source: Path, out: Path, model: Path | None = None, conf: float | None = None,
                  force: bool = False, progress: bool = True, input_width: int | None = None) -> OverlayVideo:
    """Write ``out`` (MP4, one frame per input frame, at the input's size) and ``out`` with ``.png`` (contact sheet).

    ``input_width`` runs the model smaller, as a slower robot would; ranges are drawn only where the model's
    calibration was measured at that width (``ranges`` in the result says whether they were).
    """
    out = Path(out)
    if out.suffix.lower() != ".mp4":
        raise ValueError(f"--out {out}: the overlay video is written as MP4 - name it *.mp4")
    for output in (out, out.with_suffix(".png")):  # the video and its contact sheet
        check_output_file(output, force, (Path(source),))
    detector = load_detector(model, conf=conf, input_width=input_width)
    front_end = FrontEnd(detector, min_confidence=detector.conf) if detector.usable_calibration else None
    count, fps, frames = frames_in(source)
    every = max(1, count // SHEET_TILES)
    tiles, written, writer, size = [], 0, None, None
    tmp = out.with_name(f".{out.stem}.partial.mp4")
    out.parent.mkdir(parents=True, exist_ok=True)
    try:
        for index, (name, frame, _) in enumerate(show_progress(frames, "overlay", "frame", total=count,
                                                               enabled=progress)):
            if writer is None:
                size = frame.shape[1::-1]
                if min(size) < MIN_FRAME_SIDE:
                    raise ValueError(f"{source}: its frames are {size[0]}x{size[1]}, too small to show a pole (at "
                                     f"least {MIN_FRAME_SIDE} px a side) - give the camera's full-size frames")
                writer = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*"mp4v"), fps, size)
                if not writer.isOpened():
                    raise OSError(f"{out}: OpenCV's MP4 writer refused {size[0]}x{size[1]} frames at {fps:g} fps "
                                  "here - use --images to pre-label the frames instead")
            if frame.shape[1::-1] != size:  # a folder of frames of mixed sizes: the video keeps the first's
                frame = cv2.resize(frame, size)
            found, measured = front_end.detect_and_measure(frame) if front_end else (detector(frame), [])
            drawn = draw_detections(frame, found, measured)
            writer.write(drawn)
            written += 1
            if index % every == 0 and len(tiles) < SHEET_TILES:
                tiles.append((drawn, name))
        writer.release()
        os.replace(tmp, out)
    finally:
        if writer is not None:
            writer.release()
        tmp.unlink(missing_ok=True)
    sheet = contact_sheet(tiles, out.with_suffix(".png"), columns=SHEET_COLUMNS, tile_width=SHEET_TILE_WIDTH)
    return OverlayVideo(written, fps, out, sheet, detector.conf, front_end is not None)


def draw_detections(frame: np.ndarray, detections: list[Detection], measurements: list[Measurement]) -> np.ndarray:
    """The frame with each mask tinted in its class colour and labelled: class, confidence, and the range and bearing
    of the measurement made of it, if any."""
    measured = {id(m.detection): m for m in measurements}
    out = frame.copy()
    h, w = out.shape[:2]
    scale = max(0.4, w / 1600)
    for d in detections:
        colour = np.array(CLASS_BGR[CLASSES.index(d.name)], np.float32)
        mask = d.full_mask((h, w))
        out[mask] = (0.55 * out[mask] + 0.45 * colour).astype(np.uint8)
        x0, y0 = int(d.box[0]), int(d.box[1])
        text = f"{d.name} {d.confidence:.2f}"
        if (m := measured.get(id(d))) is not None:
            text += f" {m.range_m:.2f} m {np.degrees(m.bearing_rad):+.1f} deg"
        draw_label(out, text, (x0, max(y0 - 5, 12)), colour.tolist(), scale, max(1, round(2 * scale)))
    return out
