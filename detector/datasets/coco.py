"""Read a Roboflow "COCO" segmentation export: one ``_annotations.coco.json`` beside the images of each split."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from detector.datasets.io import IMAGE_SUFFIXES
from detector.datasets.model import SPLITS, Dataset, Instance, Problem, Sample
from detector.datasets.names import canonical_class
from detector.datasets.polygons import merge_polygons, polygon_area
from detector.datasets.labels import MIN_NORMALISED_AREA

COCO_FILENAME = "_annotations.coco.json"


def find_coco_files(path: Path) -> dict[str, Path]:
    """Split name -> annotation file, for a folder of split folders, or a single JSON file (read as ``train``)."""
    if path.is_file() and path.suffix == ".json":
        return {"train": path}
    aliases = {"train": "train", "valid": "valid", "val": "valid", "test": "test"}
    found = {}
    for folder, split in aliases.items():
        candidate = path / folder / COCO_FILENAME
        if candidate.is_file() and split not in found:
            found[split] = candidate
    return found


def load_coco(path: Path) -> Dataset:
    """Read every split's COCO file; polygons in pixels become normalised, multi-part masks are joined."""
    samples: list[Sample] = []
    problems: list[Problem] = []
    for split, json_path in sorted(find_coco_files(path).items(), key=lambda kv: SPLITS.index(kv[0])):
        samples += _read_coco_split(split, json_path, problems)
    return Dataset(path, samples, problems)


def _read_coco_split(split: str, json_path: Path, problems: list[Problem]) -> list[Sample]:
    try:
        coco = json.loads(json_path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as exc:
        problems.append(Problem("error", json_path, getattr(exc, "lineno", None), f"cannot read COCO JSON ({exc})",
                                "re-export the dataset"))
        return []
    categories = {c["id"]: (c["name"], canonical_class(c["name"])) for c in coco.get("categories", [])}
    by_image: dict[int, list[dict]] = {}
    for annotation in coco.get("annotations", []):
        by_image.setdefault(annotation["image_id"], []).append(annotation)
    samples = []
    for image in coco.get("images", []):
        image_path = json_path.parent / image["file_name"]
        if image_path.suffix.lower() not in IMAGE_SUFFIXES or not image_path.is_file():
            problems.append(Problem("error", json_path, None, f"image {image['file_name']!r} is listed but missing",
                                    f"put it beside {json_path.name}"))
            continue
        size = np.array([image["width"], image["height"]], np.float64)
        instances = []
        for annotation in by_image.get(image["id"], []):
            instance = _instance(annotation, categories, size, json_path, problems)
            if instance is not None:
                instances.append(instance)
        samples.append(Sample(split, image_path, None, instances))
    return samples


def _instance(annotation: dict, categories: dict, size: np.ndarray, json_path: Path, problems: list[Problem]):
    def error(message: str, fix: str) -> None:
        problems.append(Problem("error", json_path, None, f"annotation {annotation.get('id')}: {message}", fix))

    name, code = categories.get(annotation.get("category_id"), (None, None))
    if code is None:
        return error(f"category {name!r} names no landmark", "rename the category to one of bp gp yp pb pg py")
    segmentation = annotation.get("segmentation")
    if isinstance(segmentation, dict):
        return error("RLE mask, not polygons", "export with polygon segmentation (Roboflow's COCO export does)")
    parts = [np.asarray(s, np.float64).reshape(-1, 2) / size for s in segmentation or [] if len(s) >= 6 and len(s) % 2 == 0]
    if not parts:
        return error("no polygon with at least 3 points", "draw a polygon, not only a box")
    polygon = np.clip(merge_polygons(parts), 0.0, 1.0)
    if polygon_area(polygon) < MIN_NORMALISED_AREA:
        return error("polygon has zero area", "redraw the outline")
    return Instance(code, polygon)
