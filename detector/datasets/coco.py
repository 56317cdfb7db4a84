"""Read a Roboflow "COCO" segmentation export: one ``_annotations.coco.json`` beside the images of each split."""
from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

import numpy as np

from detector.datasets.model import IMAGE_SUFFIXES, SPLITS, Dataset, Instance, Problem, Sample
from detector.datasets.names import class_codes, unknown_class_problems
from detector.datasets.orientation import stored_and_upright_size
from detector.datasets.polygons import merge_polygons, polygon_area
from detector.datasets.labels import BOX_ONLY, MIN_NORMALISED_AREA, unread_entries

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


def load_coco(path: Path, renames: dict[str, str] | None = None) -> Dataset:
    """Read every split's COCO file; polygons in pixels become normalised, multi-part masks are joined."""
    samples: list[Sample] = []
    problems: list[Problem] = []
    for split, json_path in sorted(find_coco_files(path).items(), key=lambda kv: SPLITS.index(kv[0])):
        samples += _read_coco_split(split, json_path, problems, renames)
    return Dataset(path, samples, problems)


def _read_coco_split(split: str, json_path: Path, problems: list[Problem], renames: dict[str, str] | None) -> list[Sample]:
    def error(message: str, fix: str) -> None:
        problems.append(Problem("error", json_path, None, message, fix))

    try:
        coco = json.loads(json_path.read_text(encoding="utf-8-sig"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        problems.append(Problem("error", json_path, getattr(exc, "lineno", None), f"cannot read COCO JSON ({exc})",
                                "re-export the dataset"))
        return []
    if not isinstance(coco, dict) or not all(isinstance(coco.get(k, []), list) for k in ("images", "annotations", "categories")):
        error("not a COCO file (no `images`, `annotations` and `categories` lists)", "re-export as COCO segmentation")
        return []
    first_problem = len(problems)
    named, codes = _categories(coco["categories"] if "categories" in coco else [], json_path, problems, renames)
    categories = {c["id"]: code for c, code in zip(named, codes)}
    images: dict = {}
    for image in coco.get("images", []):
        if not isinstance(image, dict) or not isinstance(image.get("file_name"), str) or "id" not in image:
            error(f"image entry {str(image)[:60]} has no `id` and `file_name`", "re-export the dataset")
        elif image["id"] in images:
            error(f"image id {image['id']!r} is used by {images[image['id']]['file_name']!r} and {image['file_name']!r}",
                  "give every image its own id (re-export)")
        else:
            images[image["id"]] = image
    by_image: dict = {}
    for annotation in coco.get("annotations", []):
        image_id = annotation.get("image_id") if isinstance(annotation, dict) else None
        if image_id not in images:
            error(f"annotation {annotation.get('id') if isinstance(annotation, dict) else annotation!r}: "
                  f"image_id {image_id!r} is not an image of this file", "re-export, or delete the annotation")
            continue
        by_image.setdefault(image_id, []).append(annotation)
    samples, outlines = [], Counter()
    index_of = {c["id"]: index for index, c in enumerate(named)}
    for image_id, image in images.items():
        image_path = json_path.parent / image["file_name"]
        if image_path.suffix.lower() not in IMAGE_SUFFIXES or not image_path.is_file():
            elsewhere = _found_elsewhere(json_path, image["file_name"])
            error(f"image {image['file_name']!r} is listed but missing beside it"
                  + (f" (it is in {elsewhere.parent})" if elsewhere else ""), f"put it beside {json_path.name}"
                  + (" (Roboflow's COCO export keeps each split's images beside its JSON)" if elsewhere else ""))
            continue
        size = _image_size(image, image_path, json_path, problems)
        if size is None:
            continue
        annotations, found = by_image.get(image_id, []), []
        instances = [inst for a in annotations if (inst := _instance(a, categories, size, json_path, found))]
        problems += found
        _, boxes = unread_entries(found)
        outlines.update(index_of[a["category_id"]] for a in annotations
                        if categories.get(a.get("category_id"), "") is None and _has_outline(a))
        samples.append(Sample(split, image_path, None, instances, len(annotations) - len(instances), boxes))
    if None in codes:  # before the split's other problems: the --rename advice must lead them
        problems[first_problem:first_problem] = unknown_class_problems(
            json_path, [c["name"] for c in named], codes, outlines, [c["id"] for c in named], "category")
    return samples


def _found_elsewhere(json_path: Path, file_name: str) -> Path | None:
    """Where an image a COCO file lists but that is not beside it lies in the export (an ``images`` folder, another
    split's folder), if anywhere."""
    root = json_path.parent.parent
    for folder in (json_path.parent / "images", *sorted(root.glob("*/")), *sorted(root.glob("*/images/"))):
        if folder != json_path.parent and (folder / file_name).is_file():
            return folder / file_name
    return None


def _has_outline(annotation: dict) -> bool:
    """Whether an annotation carries a polygon (a box-only one has an empty ``segmentation``)."""
    segmentation = annotation.get("segmentation")
    return isinstance(segmentation, (list, dict)) and bool(segmentation)


def _categories(raw: list, json_path: Path, problems: list[Problem],
                renames: dict[str, str] | None) -> tuple[list[dict], tuple[str | None, ...]]:
    """The categories in use and each one's landmark code (None: names no landmark). Roboflow's placeholder
    supercategory (id 0, the project's name, which no annotation uses) is skipped; the rest go through
    ``class_codes``."""
    used = [c for c in raw if isinstance(c, dict) and "id" in c and "name" in c]
    if len(used) != len(raw):
        problems.append(Problem("error", json_path, None, "a category has no `id` or `name`", "re-export the dataset"))
    placeholder = [c for c in used if c.get("supercategory") == "none" and c["id"] == 0 and len(used) > 1]
    named = [c for c in used if c not in placeholder]
    codes, found = class_codes([c["name"] for c in named], json_path, renames, [c["id"] for c in named], "categories")
    problems += found
    return named, codes


def _image_size(image: dict, image_path: Path, json_path: Path, problems: list[Problem]) -> np.ndarray | None:
    """The image's upright size (its EXIF orientation applied, as every reader here decodes it), read from its
    header (``poles check`` decodes the pixels); an error when COCO declares another (polygons would be scaled or
    turned wrongly)."""
    try:
        stored, upright, orientation = stored_and_upright_size(image_path)
    except (OSError, ValueError):
        problems.append(Problem("error", image_path, None, "image cannot be decoded (corrupt or not an image)",
                                "re-export or delete the image"))
        return None
    declared = (image.get("width"), image.get("height"))
    if declared != (None, None) and declared != upright:
        if declared == stored:
            problems.append(Problem("error", json_path, None, f"image {image['file_name']!r} is stored turned (EXIF "
                                    f"orientation {orientation}) and read upright as {upright[0]}x{upright[1]}, but "
                                    f"the file declares the stored {stored[0]}x{stored[1]}: its polygons were drawn "
                                    "on the unturned pixels", "re-export with Roboflow's Auto-Orient preprocessing "
                                    "(or save the images upright, without the tag, and label them again)"))
        else:
            problems.append(Problem("error", json_path, None, f"image {image['file_name']!r} is declared "
                                    f"{declared[0]}x{declared[1]} but is {upright[0]}x{upright[1]}", "re-export the "
                                    "dataset (polygons are in the declared size's pixels)"))
        return None
    return np.array(upright, np.float64)


def _instance(annotation: dict, categories: dict, size: np.ndarray, json_path: Path, problems: list[Problem]):
    def error(message: str, fix: str) -> None:
        problems.append(Problem("error", json_path, None, f"annotation {annotation.get('id')}: {message}", fix))

    if annotation.get("category_id") not in categories:
        return error(f"category_id {annotation.get('category_id')!r} is not a category of this file", "re-export")
    code = categories[annotation["category_id"]]
    segmentation = annotation.get("segmentation")
    if segmentation == [] or segmentation is None and "bbox" in annotation:
        return error(f"a box without a polygon - {BOX_ONLY}", "export from Roboflow as COCO *instance segmentation*")
    if code is None:
        return None  # the category itself is reported once
    if isinstance(segmentation, dict):
        return error("RLE mask, not polygons", "export with polygon segmentation (Roboflow's COCO export does)")
    if isinstance(segmentation, list) and segmentation and all(isinstance(v, (int, float)) for v in segmentation):
        segmentation = [segmentation]  # a flat list is one polygon
    if not isinstance(segmentation, list) or not all(isinstance(part, list) for part in segmentation):
        return error(f"segmentation {str(segmentation)[:40]} is not a list of polygons", "re-export the dataset")
    try:
        arrays = [np.asarray(part, np.float64) for part in segmentation]
    except (TypeError, ValueError):
        return error("segmentation holds something other than numbers", "re-export the dataset")
    if not all(np.isfinite(a).all() for a in arrays):
        return error("a coordinate is not finite (nan/inf)", "redraw the outline")
    parts = [a.reshape(-1, 2) for a in arrays if a.size >= 6 and a.size % 2 == 0]
    if not parts:
        return error("no polygon with at least 3 points", "draw a polygon, not only a box")
    pixels = np.concatenate(parts)
    if pixels.min() < -1 or (pixels > size + 1).any():
        return error(f"coordinates outside the {int(size[0])}x{int(size[1])} image", "redraw the outline inside the image")
    polygon = np.clip(merge_polygons([p / size for p in parts]), 0.0, 1.0)
    if polygon_area(polygon) < MIN_NORMALISED_AREA:
        return error("polygon has zero area", "redraw the outline")
    return Instance(code, polygon)
