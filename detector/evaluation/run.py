"""``poles evaluate``: run a front end over a held-out split, count, measure, and write the report."""
from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np

from rich.table import Table

from detector.console import make_console, show_progress
from detector.datasets.intake import open_dataset
from detector.datasets.io import load_dataset
from detector.datasets.model import SPLITS
from detector.datasets.polygons import polygon_to_mask
from detector.datasets.truth import load_camera_poses, load_truth
from detector.evaluation.by_width import recall_by_width, width_bin_names
from detector.evaluation.counting import (ImageEvaluation, best_threshold, confidence_sweep, confusion_matrix,
                                          evaluate_image, map_scores, outcome)
from detector.evaluation.paired import f1_difference
from detector.evaluation.plots import plot_confusion, plot_per_image, plot_recall_by_width, plot_sweep, write_overlay
from detector.evaluation.predictors import Predictor
from detector.evaluation.results import Confusion, Counts, ErrorStats, Evaluation, FrameCounts
from detector.formats import write_record
from naoslam.camera import NAO_HFOV_DEG
from naoslam.landmarks import CLASSES
from naoslam.perception.detections import Detection
from naoslam.measurement import RangeCalibration, bearing_of_column
from naoslam.shipped import COLOUR_FILTER


def evaluate(predictor: Predictor, data: Path, out: Path, split: str = "test", conf: float = 0.5,
             progress: bool = True, use_pose: bool = False, frames: int | None = None,
             check: bool = True) -> Evaluation:
    """Evaluate ``predictor`` on ``split`` of ``data`` (its first ``frames``, or all); writes ``out``/metrics.json,
    plots and overlays. ``use_pose``: give the front end each frame's camera pose where annotations.json records it,
    as on the robot. ``check`` False skips ``poles check``'s decoding of every image, for a dataset a pipeline made
    and checked itself."""
    dataset = open_dataset(data, progress=progress) if check else load_dataset(data)
    samples = dataset.split(split)[:frames]
    if not samples:
        held = [f"{name} ({count} images)" for name in SPLITS if (count := len(dataset.split(name)))]
        raise ValueError(f"{data}: the {split!r} split has no images - pick another with --split: {', '.join(held)}")
    truth = load_truth(dataset)
    out = Path(out)
    overlays = out / "errors"
    written = 0

    def write_errors(image: ImageEvaluation, frame: np.ndarray, detections: list[Detection], masks: list) -> None:
        nonlocal written
        written += write_overlay(image, frame, detections, masks, conf, overlays)

    poses = load_camera_poses(dataset) if use_pose else {}
    images = evaluate_frames(predictor, samples, truth, f"evaluating {predictor.name}", progress, write_errors, poses)
    per_image = tuple(FrameCounts(image.name, image.counts(conf)) for image in images)
    counts = sum((frame.counts for frame in per_image), Counts())
    sweep = confidence_sweep(images)
    best = max(sweep, key=lambda point: point.f1)
    outcomes = [outcome(image, conf) for image in images]
    confusion = confusion_matrix(images, outcomes, CLASSES)
    range_error, bearing_error, divide_error = _measurement_errors(images, conf, predictor)
    precision, recall, f1 = counts.precision_recall()
    metrics = Evaluation(
        model=predictor.name, data=Path(data), split=split, conf=conf, images=len(images),
        matching=predictor.matching, camera_poses=len(poses), counts=counts, precision=precision, recall=recall, f1=f1,
        mean_iou=_mean_tp_iou(images, conf), best_f1_conf=best.conf, best_f1=best.f1, sweep=tuple(sweep),
        per_image=per_image,
        confusion=Confusion((*CLASSES, "none"), tuple(tuple(int(c) for c in row) for row in confusion)),
        class_swaps=sum(len(o.swaps) for o in outcomes), duplicates=sum(len(o.duplicates) for o in outcomes),
        recall_by_width=tuple(recall_by_width(images, conf)), map=map_scores(images, CLASSES),
        range_error=range_error, bearing_error=bearing_error, divide_pixel_error=divide_error, overlays=written)
    out.mkdir(parents=True, exist_ok=True)
    plot_per_image(metrics.per_image, out / "per_image.png", predictor.name)
    plot_sweep(metrics.sweep, out / "sweep.png", predictor.name)
    plot_confusion(confusion, CLASSES, out / "confusion.png", predictor.name)
    plot_recall_by_width(metrics.recall_by_width, out / "recall_by_width.png", predictor.name)
    write_record(out / "metrics.json", "evaluation", metrics.to_json())
    return metrics


def evaluate_frames(predictor: Predictor, samples: list, truth: dict, label: str = "evaluating",
                    progress: bool = True, each_frame=None, poses: dict | None = None) -> list[ImageEvaluation]:
    """Each sample's counts against its labels, the front end given the frame's camera pose where ``poses`` has it.
    Frames stream through: only each image's compact counts stay (and ``each_frame(image, frame, detections,
    label_masks)`` sees the frame while its masks are in hand), so memory does not grow with the frames."""
    images = []
    for sample in show_progress(samples, label, "img", enabled=progress):
        frame = cv2.imread(str(sample.image))
        h, w = frame.shape[:2]
        masks = [polygon_to_mask(inst.pixels(w, h), w, h) for inst in sample.instances]
        entries = truth.get(sample.image.name) or [None] * len(sample.instances)
        detections = predictor(frame, (poses or {}).get(sample.image.name))
        image = evaluate_image(sample.image.name, [i.cls for i in sample.instances], masks, entries, detections,
                               frame.shape, predictor.matching)
        if each_frame is not None:
            each_frame(image, frame, detections, masks)
        images.append(image)
    return images


def _mean_tp_iou(images: list[ImageEvaluation], conf: float) -> float | None:
    """Mean IoU (mask or box) of true positives (None for the colour filter, which has no masks)."""
    if images and images[0].matching == "point":
        return None
    ious = [image.overlap[p, r] for image in images for p, r in image.match(conf)]
    return float(np.mean(ious)) if ious else 0.0


def _stats(values: list[float]) -> ErrorStats | None:
    """Statistics of the absolute ``values``; None where there are none."""
    if not values:
        return None
    a = np.abs(np.array(values))
    return ErrorStats(float(a.mean()), float(np.median(a)), float(np.percentile(a, 90)), len(values))


def _measurement_errors(images: list[ImageEvaluation], conf: float,
                        predictor: Predictor) -> tuple[ErrorStats | None, ErrorStats | None, ErrorStats | None]:
    """Range (m), bearing (deg) and, for the colour filter, band-divide pixel errors of true positives."""
    range_err, bearing_err, pixel_err = [], [], []
    calibration = predictor.calibration
    for image in images:
        for p, r in image.match(conf):
            detection = image.detections[p]
            truth = image.truth[r] if r < len(image.truth) else None
            if not truth:
                continue
            width = truth.get("image_width") or 640
            if truth.get("bearing_rad") is not None:
                hfov = calibration.hfov_deg if calibration else NAO_HFOV_DEG
                bearing_err.append(math.degrees(bearing_of_column(detection.centre_column, width, hfov)
                                                - truth["bearing_rad"]))
            if truth.get("range_m") is not None and calibration is not None:
                estimate = _range(detection, calibration, width)
                if estimate is not None:
                    range_err.append(estimate - truth["range_m"])
            if detection.band_centres is not None and truth.get("band_divide_centre_px"):
                pixel_err.append(math.dist(detection.divide_centre, truth["band_divide_centre_px"]))
    return _stats(range_err), _stats(bearing_err), _stats(pixel_err)


def _range(detection: Detection, calibration: RangeCalibration, image_width: int) -> float | None:
    """The range the detection measures: the colour filter's from its band distance, a model's from its rotated box
    (None where the calibration has no law for it or the mask is empty)."""
    column = detection.centre_column
    if detection.band_centres is not None:
        if calibration.colour_law is None:
            return None
        return calibration.colour_range(detection.band_distance_px, image_width, column=column)[0]
    if detection.rotated_box is None:
        return None
    box = detection.rotated_box
    return calibration.range_from_box(box.width, box.height, image_width, column=column)[0]


def _width_recall(m: Evaluation, index: int) -> str:
    """Recall in one width bin, with its label count ("80 % of 10"); "-" for an empty bin."""
    row = m.recall_by_width[index]
    return f"{100 * row.recall:.0f} % of {row.labels}" if row.labels else "-"


def _localisation(m: Evaluation) -> str:
    if m.mean_iou is not None:
        return f"{m.matching} IoU {m.mean_iou:.4f}"
    return f"{m.divide_pixel_error.mean:.2f} px" if m.divide_pixel_error else "-"


def _error(stats: ErrorStats | None, unit: str, digits: int) -> str:
    return f"{stats.median:.{digits}f} / {stats.p90:.{digits}f} {unit}" if stats else "-"


#: Recall in each pole-width bin, one row per bin.
_WIDTH_ROWS = {f"  poles {name} wide": (lambda m, i=i: _width_recall(m, i)) for i, name in enumerate(width_bin_names())}
#: Rows of the comparison table: label and how to show it from an evaluation.
TABLE_ROWS = {
    "images": lambda m: str(m.images),
    "matched to labels by": lambda m: {"point": "band-dividing point"}.get(m.matching, f"{m.matching} IoU >= 0.5"),
    "threshold (the counts')": lambda m: "any" if m.model == COLOUR_FILTER else f"{m.conf:.2f}",
    "TP / FP / FN / TN": lambda m: f"{m.counts.tp} / {m.counts.fp} / {m.counts.fn} / {m.counts.tn}",
    "FP: class swaps / duplicates": lambda m: f"{m.class_swaps} / {m.duplicates}",
    "precision": lambda m: f"{100 * m.precision:.1f} %",
    "recall": lambda m: f"{100 * m.recall:.1f} %",
    "F1": lambda m: f"{m.f1:.3f}",
    **_WIDTH_ROWS,
    "localisation": _localisation,
    "mAP50 / mAP50-95": lambda m: f"{m.map.map50:.3f} / {m.map.map50_95:.3f}" if m.map else "-",
    "range error median / p90": lambda m: _error(m.range_error, "m", 3),
    "bearing error median / p90": lambda m: _error(m.bearing_error, "deg", 2),
    "best-F1 threshold (F1)": lambda m: _best_f1(m),
}


def _best_f1(m: Evaluation) -> str:
    threshold = best_threshold(list(m.sweep))
    return f"{'any' if threshold is None else f'{threshold:.2f}'} ({m.best_f1:.3f})"


def print_metrics(rows: list[Evaluation]) -> None:
    """Side-by-side table of several evaluations, like the thesis's table 4.2, titled with the split it scored."""
    split = rows[0].split if rows else "test"
    title = ("held-out frames" if split != "train" else "TRAINING frames (not held out: a model scores higher on "
             "frames it learnt)") + f" of the {split} split: TP = same class and overlap as each column says"
    table = Table(title=title)
    table.add_column("")
    for m in rows:
        table.add_column(m.model, justify="right")
    for label, cell in TABLE_ROWS.items():
        table.add_row(label, *(cell(m) for m in rows))
    if len(rows) > 1:
        table.add_row("F1 - the first's (95 % over frames)", "-", *(_versus(rows[0], m) for m in rows[1:]))
    make_console().print(table)


def _versus(first: Evaluation, other: Evaluation) -> str:
    change = f1_difference(first.per_image, other.per_image)
    return f"{change.difference:+.3f} ({change.low:+.3f} to {change.high:+.3f})"
