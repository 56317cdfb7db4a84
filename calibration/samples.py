"""Pole sizes in pixels paired with their true range: from the labels' masks or from a model's masks."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from detector.console import show_progress
from detector.datasets.intake import open_dataset
from detector.datasets.polygons import polygon_to_mask
from detector.datasets.model import Dataset
from detector.datasets.truth import ImageTruth, load_truth
from detector.matching import box_iou, mask_box, mask_iou
from naoslam.camera import NAO_HFOV_DEG, CameraPose, PinholeCamera
from naoslam.perception.colour_filter import ColourFilter
from naoslam.perception.detections import Detection, mask_centre_column, rotated_box_of_mask
from naoslam.perception.pole_model import PoleModel
from naoslam.ground import GroundView, PoleExtent
from naoslam.landmarks import PoleGeometry
from naoslam.measurement import band_spacing_per_cm, on_axis_size


@dataclass(frozen=True)
class SizeSample:
    """One pole of known range, measured in one image."""

    image: str
    cls: str
    range_m: float
    width_px: float
    height_px: float
    centre_column: float
    image_width: int
    partial: bool = False
    bearing_rad: float | None = None
    #: What the colour filter measures of this pole (px between its band centres), None where it misses it.
    band_distance_px: float | None = None
    foot_range_m: float | None = None
    foot_range_std: float | None = None


@dataclass(frozen=True)
class RangedDataset:
    """A checked dataset and the true range of its poles (``truth.ImageTruth`` per image)."""

    dataset: Dataset
    truth: dict[str, ImageTruth]


def open_ranged(data: Path, truth_csv: Path | None = None, progress: bool = True) -> RangedDataset:
    """The dataset at ``data`` with its poles' true ranges (annotations.json or ``truth_csv``); refused when it is
    not a readable dataset or no pole has a range."""
    dataset = open_dataset(data, progress=progress)
    truth = load_truth(dataset, truth_csv)
    if not any(t and t.get("range_m") is not None for entries in truth.values() for t in entries):
        annotations = dataset.root / "annotations.json"
        if truth_csv is None and annotations.is_file():
            raise ValueError(f"{annotations}: no landmark in it has a true range (`poles synth` writes `images` -> "
                             "each image's `landmarks`, in label order, each with `range_m`) - write it in that "
                             "layout, or pass --truth image,class,range_m CSV")
        raise ValueError(f"{truth_csv or data}: no landmark has a true range - add annotations.json (`poles synth "
                         "--calibration-shots` and `--walk` write one) or, for --data, pass --truth "
                         "image,class,range_m CSV")
    return RangedDataset(dataset, truth)


#: Confidence a model's detection needs to measure a pole (low: the labelled pole picks its detection by mask IoU).
MEASURE_CONF = 0.25


def measure_samples(ranged: RangedDataset, detector: PoleModel | None = None, progress: bool = True,
                    hfov_deg: float = NAO_HFOV_DEG) -> list[SizeSample]:
    """Measure every pole with a true range: its labelled mask, or the ``detector``'s best same-class detection (and
    its foot-row range where the image's camera pose is known); and what the colour filter measures of it, so that
    its law is fitted on the band distances it will measure on the robot."""
    dataset, truth = ranged.dataset, ranged.truth
    colour_filter = ColourFilter()
    samples = []
    for sample in show_progress(dataset.samples, "measuring", "img", enabled=progress):
        entries = truth.get(sample.image.name)
        if not entries:
            continue
        frame = cv2.imread(str(sample.image))
        height, width = frame.shape[:2]
        detections = detector(frame) if detector else None
        coloured = colour_filter(frame)
        for instance, entry in zip(sample.instances, entries):
            if not entry or entry.get("range_m") is None:
                continue
            label_mask = polygon_to_mask(instance.pixels(width, height), width, height)
            if detections is None:
                box, column = rotated_box_of_mask(label_mask), mask_centre_column(label_mask) if label_mask.any() else None
                extent = PoleExtent.of_mask(label_mask)
            else:
                found = _matching_detection(detections, instance.cls, label_mask)
                if found is None:
                    continue
                box, column, extent = found.rotated_box, found.centre_column, found.extent
            if box is None:
                continue
            view = _ground_view(entry.get("camera"), width, height, hfov_deg)
            range_m, bearing = float(entry["range_m"]), entry.get("bearing_rad")
            box_width, box_height = box.width, box.height
            if view is not None:  # the laws are fitted on what a level camera sees, as measurements are taken
                box_width, box_height = view.level_size(box_width, box_height, range_m,
                                                        float(view.camera.bearing_of_column(column)))
            foot = view.foot_of(extent) if view is not None and extent is not None else None
            partial = entry.get("partial")
            if partial is None:  # a truth CSV does not say: a pole whose outline reaches the border is cut
                partial = touches_border(instance.polygon)
            samples.append(SizeSample(sample.image.name, instance.cls, range_m, box_width, box_height,
                                      column, width, bool(partial), bearing,
                                      _colour_band_distance(coloured, instance.cls, label_mask),
                                      foot.range_m if foot else None, view.foot_range_std(foot) if foot else None))
    if not samples:
        raise ValueError(f"{dataset.root}: no pole with a true range could be measured"
                         + (f" - {detector.path} found none of them" if detector else ""))
    return samples


#: Mask IoU a detection needs with a labelled pole to be taken as that pole's measurement.
MATCH_IOU = 0.5


def _matching_detection(detections, cls: str, label_mask: np.ndarray):
    """The detection of class ``cls`` whose mask (a box-only detection: whose box) overlaps the labelled pole's
    most (IoU >= ``MATCH_IOU``), or None."""
    same = [d for d in detections if d.name == cls]
    if not same:
        return None
    if same[0].box_only:
        overlap = box_iou([d.box for d in same], [mask_box(label_mask)])[:, 0]
    else:
        overlap = mask_iou([d.full_mask(label_mask.shape) for d in same], [label_mask])[:, 0]
    best = int(np.argmax(overlap))
    return same[best] if overlap[best] >= MATCH_IOU else None


def _colour_band_distance(found: list[Detection], cls: str, label_mask: np.ndarray) -> float | None:
    """The colour filter's band distance (px) for a labelled pole: its detection of that class whose band-dividing
    point lies on the pole's mask, or None where the filter misses the pole."""
    height, width = label_mask.shape
    for detection in found:
        x, y = (int(v) for v in detection.divide_centre)
        if detection.name == cls and 0 <= x < width and 0 <= y < height and label_mask[y, x]:
            return detection.band_distance_px
    return None


def _ground_view(camera: dict | None, width: int, height: int, hfov_deg: float) -> GroundView | None:
    """The image's camera over the floor when its pose is known (``annotations.json``'s ``camera``), else None."""
    if not camera:
        return None
    return GroundView(PinholeCamera(width, height, hfov_deg),
                      CameraPose(z=camera["height_m"], pitch=camera["pitch_rad"], roll=camera["roll_rad"]))


#: How close (normalised) an outline must come to the image border to count as cut by it.
BORDER_MARGIN = 0.002


def touches_border(polygon: np.ndarray) -> bool:
    """True when a normalised outline reaches the image border (the pole is cut, its height is not its own)."""
    return bool(polygon.min() <= BORDER_MARGIN or polygon.max() >= 1.0 - BORDER_MARGIN)


def as_arrays(samples: list[SizeSample], reference_width: int, hfov_deg: float | None = None,
              geometry: PoleGeometry = PoleGeometry()) -> dict[str, np.ndarray]:
    """Columns of the samples, pixel sizes scaled to ``reference_width`` and, given the camera's ``hfov_deg``, taken
    to the optical axis (:func:`naoslam.measurement.on_axis_size`; a sample without a centre column is kept as is);
    ``colour``: the colour filter's band distance in px per cm of band spacing, taken to the axis the same way (NaN
    where it missed the pole)."""
    sizes = [on_axis_size(s.width_px, s.height_px, s.centre_column, s.image_width, hfov_deg)
             if hfov_deg is not None and s.centre_column is not None else (s.width_px, s.height_px) for s in samples]
    colour = [band_spacing_per_cm(s.band_distance_px, s.image_width, reference_width, geometry, s.centre_column,
                                  hfov_deg) if s.band_distance_px is not None else np.nan for s in samples]
    scale = np.array([reference_width / s.image_width for s in samples])
    return {"range": np.array([s.range_m for s in samples]), "width": np.array([w for w, _ in sizes]) * scale,
            "height": np.array([h for _, h in sizes]) * scale, "partial": np.array([s.partial for s in samples]),
            "colour": np.array(colour)}


def measures_law(columns: dict[str, np.ndarray], size: str) -> np.ndarray:
    """Which rows of :func:`as_arrays` measure the ``size`` law: every pole for width, whole poles for height (a pole
    cut by the border is not its own height), the poles the colour filter found for colour."""
    if size == "colour":
        return np.isfinite(columns["colour"])
    return np.ones_like(columns["partial"]) if size == "width" else ~columns["partial"]
