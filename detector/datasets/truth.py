"""Ground truth beyond the labels: true range, bearing and band geometry per landmark.

Read from ``annotations.json`` (written by ``poles synth``; the real-poles set has the same ``images`` ->
``landmarks`` layout), whose landmarks follow the label file's lines in order, or from a CSV
``image,class,range_m`` with one row per landmark.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

from detector.datasets.io import csv_rows
from detector.datasets.model import Dataset, DatasetError, Problem
from detector.datasets.names import canonical_class
from naoslam.camera import CameraPose
from naoslam.ground import ground_plane_problem

#: Ground truth of one image: one dict per label line (None where nothing is known about that instance).
ImageTruth = list[dict | None]


def load_truth(dataset: Dataset, csv_path: Path | None = None) -> dict[str, ImageTruth]:
    """Truth per image file name, aligned with each sample's instances; empty when the dataset has none."""
    if csv_path is not None:
        return _from_csv(dataset, Path(csv_path))
    path = dataset.root / "annotations.json"
    if not path.is_file():
        return {}
    images = _our_annotations(path)
    if images is None:
        print(f"note: {path} is not an annotations.json of `poles synth` (no images -> landmarks mapping); ignored")
        return {}
    truth, odd = {}, []
    for sample in dataset.samples:
        entry = images.get(sample.image.name)
        if not isinstance(entry, dict):
            if entry is not None:
                odd.append(sample.image.name)
            continue
        landmarks = [lm for lm in entry.get("landmarks", []) if isinstance(lm, dict)]
        if [lm.get("cls") for lm in landmarks] != [inst.cls for inst in sample.instances]:
            raise DatasetError([Problem("error", path, None,
                                        f"landmarks of {sample.image.name} do not follow its label file's classes",
                                        "regenerate annotations.json with the labels, or pass a CSV with --truth")])
        for landmark in landmarks:
            if "range_m" in landmark and not _is_distance(landmark["range_m"]):
                raise DatasetError([Problem("error", path, None,
                                            f"{sample.image.name}: range_m {landmark['range_m']!r} of its "
                                            f"{landmark.get('cls')} is not a distance",
                                            "give each landmark's true range in metres, a positive number, or "
                                            "leave range_m out")])
        truth[sample.image.name] = [dict(lm, image_width=entry.get("width"), camera=entry.get("camera"))
                                    for lm in landmarks]
    if odd:
        print(f"note: {path}: the entries of {len(odd)} image(s) ({', '.join(odd[:3])}) are not `poles synth`'s "
              "(an object with `landmarks`); their truth is ignored")
    names = {sample.image.name for sample in dataset.samples}
    if images and not names & set(images):
        print(f"note: {path} names none of the dataset's {len(names)} images (it names {', '.join(list(images)[:3])}"
              f"{', ...' if len(images) > 3 else ''}); its truth is ignored")
    return truth


def _is_distance(value) -> bool:
    """A range that a calibration may use: None (not known), or a finite number of metres above 0."""
    if value is None:
        return True
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value) and value > 0


def load_camera_poses(dataset: Dataset) -> dict[str, CameraPose]:
    """The camera's pose (height, pitch, roll) of each image whose ``annotations.json`` entry records one (``poles
    synth`` writes them), by file name; empty without such a file. A pose with no floor under it is left out
    (``camera_pose_problems`` says why)."""
    return {name: pose for name, pose in _recorded_poses(dataset).items() if isinstance(pose, CameraPose)}


def camera_pose_problems(dataset: Dataset) -> dict[str, str]:
    """Why each recorded camera pose that no front end can measure on is left out, by file name."""
    return {name: pose for name, pose in _recorded_poses(dataset).items() if isinstance(pose, str)}


def _recorded_poses(dataset: Dataset) -> dict[str, CameraPose | str]:
    """Each image's recorded camera pose, or why it cannot be used; images that record none are absent."""
    images = _our_annotations(dataset.root / "annotations.json") or {}
    poses: dict[str, CameraPose | str] = {}
    for name, entry in images.items():
        camera = entry.get("camera") if isinstance(entry, dict) else None
        if camera is None:
            continue
        try:
            pose = CameraPose(z=float(camera["height_m"]), pitch=float(camera["pitch_rad"]),
                              roll=float(camera["roll_rad"]))
        except (TypeError, KeyError, ValueError):
            poses[name] = "its camera entry needs the numbers height_m, pitch_rad and roll_rad"
            continue
        poses[name] = ground_plane_problem(pose) or pose
    return poses


def read_annotations(path: Path) -> dict | None:
    """An annotations.json in this project's schema (an object with an ``images`` mapping), or None for a missing
    or any other file."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return None
    return data if isinstance(data, dict) and isinstance(data.get("images"), dict) else None


def _our_annotations(path: Path) -> dict | None:
    """The ``images`` mapping of an annotations.json in this project's schema, or None for any other file."""
    data = read_annotations(path)
    return data["images"] if data is not None else None


def _from_csv(dataset: Dataset, path: Path) -> dict[str, ImageTruth]:
    """Rows ``image,class,range_m``: each row gives the range of that image's (only) instance of that class."""
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such truth CSV (columns image,class,range_m)")
    by_image = {s.image.name: s for s in dataset.samples}
    truth: dict[str, ImageTruth] = {}
    for line, row in csv_rows(path, ("image", "class", "range_m")):
        sample = by_image.get(Path(row["image"]).name)
        cls = canonical_class(row["class"])
        try:
            range_m = float(row["range_m"])
        except ValueError:
            raise ValueError(f"{path}:{line}: range_m {row['range_m']!r} is not a number") from None
        if not math.isfinite(range_m) or range_m <= 0:
            raise ValueError(f"{path}:{line}: range_m {row['range_m']!r} must be a positive distance in metres")
        if cls is None:
            raise ValueError(f"{path}:{line}: class {row['class']!r} names no landmark - use one of bp gp yp pb pg py")
        if sample is None:
            raise ValueError(f"{path}:{line}: image {row['image']!r} is not in {dataset.root}")
        matches = [i for i, inst in enumerate(sample.instances) if inst.cls == cls]
        if len(matches) != 1:
            raise ValueError(f"{path}:{line}: {row['image']} has {len(matches)} labelled {cls!r} poles; "
                             "a CSV row needs exactly one")
        entry = truth.setdefault(sample.image.name, [None] * len(sample.instances))
        entry[matches[0]] = {"cls": cls, "range_m": range_m}
    return truth
