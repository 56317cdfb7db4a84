"""Read a dataset in the Roboflow "YOLOv8" segmentation layout (or a COCO export), and write the layout atomically."""
from __future__ import annotations

import csv
import json
import os
import shutil
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType

import cv2
import numpy as np
import yaml

from detector.datasets.coco import find_coco_files, load_coco
from detector.datasets.jpeg import truncated_jpeg
from detector.datasets.labels import format_label_line, parse_label_file, unread_entries
from detector.datasets.model import IMAGE_SUFFIXES, SPLITS, Dataset, DatasetError, Instance, Problem, Sample
from detector.datasets.names import class_codes, unknown_class_problems
from detector.atomic import atomic_folder
from detector.outputs import check_output_folder, mark_output
from detector.records import JsonRecord
from naoslam.landmarks import CLASSES

#: The kind of output a dataset folder is (``detector.outputs``).
DATASET = "dataset"
#: data.yaml key -> split folder name.
YAML_SPLIT_KEYS = {"train": "train", "val": "valid", "test": "test"}


def decode_frame(path: Path) -> np.ndarray:
    """A frame's file decoded whole as BGR, or a ``ValueError`` that says why it cannot be: unreadable, not an image,
    or a truncated JPEG, which OpenCV reads from its file with the missing rows grey after one libjpeg warning."""
    try:
        data = np.fromfile(path, np.uint8)
    except OSError as exc:
        raise ValueError(f"cannot be read ({exc.strerror})") from None
    if truncated_jpeg(data.tobytes()):
        raise ValueError("cannot be decoded whole (a truncated JPEG: its data stop before the end marker)")
    image = cv2.imdecode(data, cv2.IMREAD_COLOR) if data.size else None
    if image is None:
        raise ValueError("cannot be decoded as an image")
    return image


def require_decodable(paths: list[Path]) -> None:
    """Refuse a list of frames before a long run over them starts if any cannot be decoded whole (``decode_frame``),
    naming the first and counting the rest, so a bad frame late in a recording costs a few seconds of decoding, not
    the run's work."""
    faults = []
    for path in paths:
        try:
            decode_frame(path)
        except ValueError as fault:
            faults.append((path, fault))
    if faults:
        (first, fault), more = faults[0], f" (and {len(faults) - 1} more)" if len(faults) > 1 else ""
        raise ValueError(f"{first}{more}: {fault} - remove it or re-save it; nothing was written")


def csv_rows(path: Path, columns: tuple[str, ...]) -> Iterator[tuple[int, dict[str, str]]]:
    """(line, row) of a person's CSV whose header holds ``columns`` (other columns allowed): UTF-8 with or without a
    byte-order mark, spaces after the commas allowed, blank lines skipped and counted, so ``line`` is the one an
    editor shows. A missing column or a row that leaves one of ``columns`` empty is refused by its line."""
    with path.open(newline="", encoding="utf-8-sig", errors="replace") as handle:
        reader = csv.DictReader(handle, skipinitialspace=True)
        if not reader.fieldnames or not set(columns) <= set(reader.fieldnames):
            raise ValueError(f"{path}:1: header must be {','.join(columns)} (got {reader.fieldnames})")
        for row in reader:
            empty = [column for column in columns if not row.get(column)]
            if empty:
                raise ValueError(f"{path}:{reader.line_num}: no value for {', '.join(empty)} - give every row "
                                 f"{','.join(columns)}")
            yield reader.line_num, row


def load_dataset(path: str | Path, renames: dict[str, str] | None = None) -> Dataset:
    """Read a dataset: a folder with ``data.yaml`` (or the yaml itself), or a Roboflow COCO export folder.

    ``renames`` maps a class name of the export to a landmark code before it is read (``--rename``). Problems are
    collected in ``Dataset.problems``; commands read datasets through ``intake.open_dataset``, which refuses errors.
    """
    path = Path(path)
    if not path.exists():
        raise DatasetError([Problem("error", path, None, "no such file or folder", "give the dataset folder (with data.yaml)")])
    yaml_path = path if path.is_file() and path.suffix in (".yaml", ".yml") else path / "data.yaml"
    if yaml_path.is_file():
        return _with_images_required(_load_yolo(yaml_path, renames), yaml_path,
                                     "the layout is train/images, valid/images, test/images beside data.yaml")
    if path.is_dir() and find_coco_files(path):
        return _with_images_required(load_coco(path, renames), path,
                                     "export the dataset with its images (each split's folder beside its JSON)")
    if path.is_file() and path.suffix.lower() == ".zip":
        raise DatasetError([Problem("error", path, None, "a zip archive, not a dataset folder",
                                    f"unzip it first (unzip {path.name} -d {path.stem}) and give that folder")])
    below = _datasets_one_folder_down(path) if path.is_dir() else []
    fix = (f"give the folder that holds it: {' or '.join(map(str, below))}" if below else
           "point to a Roboflow 'YOLOv8' or 'COCO' segmentation export folder")
    raise DatasetError([Problem("error", path, None, "neither data.yaml nor a COCO _annotations.coco.json found"
                                + (" here, but one folder down" if below else ""), fix)])


def _datasets_one_folder_down(folder: Path) -> list[Path]:
    """The subfolders of ``folder`` that hold a dataset (an unzipped export often sits one folder down)."""
    return [sub for sub in sorted(folder.iterdir()) if sub.is_dir() and not sub.name.startswith(".")
            and ((sub / "data.yaml").is_file() or find_coco_files(sub))]


def _with_images_required(dataset: Dataset, source: Path, fix: str) -> Dataset:
    """``dataset``, with an error added when no split holds an image (every command needs some)."""
    if not any(sample.image for sample in dataset.samples):
        dataset.problems.append(Problem("error", source, None, "no images found in any split", fix))
    return dataset


def _load_yolo(yaml_path: Path, renames: dict[str, str] | None) -> Dataset:
    root = yaml_path.parent
    problems: list[Problem] = []
    try:
        config = yaml.safe_load(yaml_path.read_text(encoding="utf-8-sig"))
    except UnicodeDecodeError as exc:
        raise DatasetError([Problem("error", yaml_path, None, f"not UTF-8 text ({exc.reason} at byte {exc.start})",
                                    "save data.yaml as UTF-8")]) from None
    except (OSError, yaml.YAMLError) as exc:
        line = getattr(getattr(exc, "problem_mark", None), "line", None)
        raise DatasetError([Problem("error", yaml_path, line + 1 if line is not None else None,
                                    f"cannot read YAML ({str(exc).splitlines()[0]})", "fix the YAML syntax")]) from None
    if not isinstance(config, dict):
        raise DatasetError([Problem("error", yaml_path, None, f"holds a {type(config).__name__}, not a mapping",
                                    "write `train:`, `val:`, `test:` and `names:` keys as Roboflow does")])
    raw_names, names = _class_names(yaml_path, config, problems, renames)
    samples: list[Sample] = []
    unknown_uses: Counter = Counter()
    base = root / str(config["path"]) if config.get("path") else root
    if not base.is_dir():
        raise DatasetError([Problem("error", yaml_path, None, f"path: {config['path']!r} names no folder (a data.yaml "
                                    "from another machine?)", "delete the `path:` line, so the splits are read beside "
                                    "data.yaml, or correct it")])
    for key, split in YAML_SPLIT_KEYS.items():
        images_dir = _split_folder(base, config.get(key), split)
        if images_dir is None:
            if isinstance(config.get(key), str):
                problems.append(Problem("warning", yaml_path, None, f"{key}: {config[key]!r} names no folder: "
                                        f"the {split} split is empty", f"create {split}/images or fix the path"))
            continue
        samples += _read_split(split, images_dir, names, problems, unknown_uses)
    beyond = sorted(i for i in unknown_uses if i >= len(names))
    if beyond:  # first too: one short `names` list explains every line that uses the classes it leaves out
        declared = f" (nc: {config['nc']})" if "nc" in config and config["nc"] != len(raw_names) else ""
        problems.insert(0, Problem("error", yaml_path, None, f"`names` lists {len(raw_names)} class(es){declared} but "
                                   f"{sum(unknown_uses[i] for i in beyond):,} label line(s) use class id(s) "
                                   f"{', '.join(map(str, beyond[:5]))}{' ...' if len(beyond) > 5 else ''}",
                                   "list every class of the export in `names`, in its class order (Roboflow's "
                                   "data.yaml does), or delete those lines"))
    if None in names:  # first: the one line with the --rename advice must not sink under per-file problems
        problems[:0] = unknown_class_problems(yaml_path, raw_names, names, unknown_uses)
    problems += _duplicate_stems(samples)
    return Dataset(root, samples, problems, (base,) if base != root else ())


def _class_names(yaml_path: Path, config: dict, problems: list[Problem],
                 renames: dict[str, str] | None) -> tuple[list, tuple[str | None, ...]]:
    """The class names data.yaml declares, in id order, and the landmark code of each (None: names no landmark)."""
    raw = config.get("names")
    if isinstance(raw, dict):
        raw = _names_by_id(yaml_path, raw)
    if not isinstance(raw, list) or not raw:
        raise DatasetError([Problem("error", yaml_path, None, "no `names` list",
                                    "add `names: ['bp', 'gp', 'yp', 'pb', 'pg', 'py']` (in your class order)")])
    names, found = class_codes(raw, yaml_path, renames)
    problems += found
    if "nc" in config and config["nc"] != len(raw):
        problems.append(Problem("warning", yaml_path, None, f"nc is {config['nc']} but names has {len(raw)} entries",
                                "set nc to the length of names"))
    return raw, names


def _names_by_id(yaml_path: Path, names: dict) -> list:
    """``names: {0: bp, 1: gp, ...}`` (as Ultralytics writes it) as the list of names in class-id order; ids must run
    0, 1, 2 ... (sorted as text, 10 came before 2 and every later class took another's name)."""
    try:
        ids = sorted(int(key) for key in names)
    except (TypeError, ValueError):
        ids = []
    if ids != list(range(len(names))):
        raise DatasetError([Problem("error", yaml_path, None, f"`names` keys {list(names)} are not the class ids "
                                    f"0-{len(names) - 1}", "key each name by its class id, `names: {0: bp, 1: gp}`, "
                                    "or give a list in class order")])
    by_id = {int(key): name for key, name in names.items()}
    return [by_id[i] for i in ids]


def _split_folder(base: Path, value, split: str) -> Path | None:
    """The images folder of one split: the yaml value relative to the yaml (Roboflow writes ``../train/images``)."""
    candidates = [base / split / "images"]
    if isinstance(value, str):
        candidates = [base / value] + ([base / value[3:]] if value.startswith("../") else []) + candidates
    return next((c.resolve() for c in candidates if c.is_dir()), None)


def _read_split(split: str, images_dir: Path, names, problems: list[Problem], unknown_uses: Counter) -> list[Sample]:
    """The samples of one split's images folder and the labels folder beside it; a folder that cannot be listed is
    one problem naming it (the split then reads as empty)."""
    try:
        return _read_split_folders(split, images_dir, names, problems, unknown_uses)
    except OSError as exc:
        folder = Path(exc.filename) if exc.filename else images_dir
        problems.append(Problem("error", folder, None, f"folder cannot be read ({exc.strerror or exc})",
                                f"give yourself read access (chmod -R u+rX {folder}) or copy the dataset"))
        return []


def _read_split_folders(split: str, images_dir: Path, names, problems: list[Problem],
                        unknown_uses: Counter) -> list[Sample]:
    labels_dir = images_dir.parent / "labels"
    images = {p.stem: p for p in sorted(images_dir.iterdir()) if p.suffix.lower() in IMAGE_SUFFIXES}
    seen: dict[str, Path] = {}
    for p in sorted(images_dir.iterdir()):
        if p.suffix.lower() in IMAGE_SUFFIXES:
            if p.stem in seen:
                problems.append(Problem("error", p, None, f"same file stem as {seen[p.stem].name}: one label cannot serve both",
                                        "rename or delete one of the two images"))
            seen[p.stem] = p
    labels = {p.stem: p for p in sorted(labels_dir.glob("*.txt"))} if labels_dir.is_dir() else {}
    samples = []
    for stem in sorted(set(images) | set(labels)):
        image, label = images.get(stem), labels.get(stem)
        instances: list[Instance] = []
        unread = boxes = 0
        if label is not None:
            instances, found = parse_label_file(label, names, unknown_uses)
            unread, boxes = unread_entries(found)
            problems += found
            if image is None:
                problems.append(Problem("error", label, None, "label without an image",
                                        f"add {stem}.jpg to {images_dir} or delete the label"))
        else:
            problems.append(Problem("note", image, None, "image without a label file: read as a negative (no landmark)",
                                    "add an empty label file to make that explicit"))
        samples.append(Sample(split, image, label, instances, unread, boxes))
    return samples


def _duplicate_stems(samples: list[Sample]) -> list[Problem]:
    first: dict[str, Sample] = {}
    problems = []
    for sample in samples:
        if sample.image is None:
            continue
        other = first.setdefault(sample.stem, sample)
        if other is not sample and other.split != sample.split:
            problems.append(Problem("error", sample.image, None,
                                    f"the same file name is in {other.split} too ({other.image}): a leak between splits",
                                    "keep each image in one split only"))
    return problems


@dataclass(frozen=True)
class SplitCounts(JsonRecord):
    """Frames per split of a dataset."""

    train: int
    valid: int
    test: int


class DatasetWriter:
    """Write a dataset in the Roboflow layout into a temporary sibling folder, then move it into place.

    Nothing appears at ``out`` unless every sample was written; an existing ``out`` is replaced only with
    ``force``, and never when it is (or holds, or lies inside) one of the ``protect`` folders (the inputs).
    """

    def __init__(self, out: str | Path, *, force: bool = False, protect: tuple[Path, ...] = ()):
        self.out = check_output_folder(out, force, protect, DATASET)
        self.force = force
        self.counts = {split: 0 for split in SPLITS}

    def __enter__(self) -> "DatasetWriter":
        self._folder = atomic_folder(self.out)
        self.tmp = self._folder.__enter__()
        for split in SPLITS:
            (self.tmp / split / "images").mkdir(parents=True)
            (self.tmp / split / "labels").mkdir(parents=True)
        return self

    def add(self, split: str, filename: str, image: bytes | Path, instances: list[Instance], link: bool = False) -> Path:
        """Add one image (encoded bytes, or a file to copy unchanged, or to link to with ``link``) and its instances,
        written by class name in the canonical class order; returns the image's final path."""
        if split not in SPLITS:
            raise ValueError(f"unknown split {split!r}; expected one of {SPLITS}")
        target = self.tmp / split / "images" / filename
        if isinstance(image, Path) and link:
            _link_or_copy(image, target)
        elif isinstance(image, Path):
            shutil.copyfile(image, target)
        else:
            target.write_bytes(image)
        lines = [format_label_line(CLASSES.index(i.cls), i.polygon) for i in instances]
        (self.tmp / split / "labels" / f"{Path(filename).stem}.txt").write_text("".join(f"{line}\n" for line in lines))
        self.counts[split] += 1
        return self.out / split / "images" / filename

    @property
    def frames(self) -> SplitCounts:
        """Frames written so far, per split."""
        return SplitCounts(**self.counts)

    def copy_sample(self, sample: Sample) -> None:
        """Copy an image byte for byte with its instances, written by class name in this dataset's class order
        (the input may order its classes differently, or be a COCO export without label files)."""
        self.add(sample.split, sample.image.name, sample.image, sample.instances)

    def write_text(self, relative: str, text: str) -> None:
        """Add any other file (a report, annotations.json) at a path relative to the dataset root."""
        target = self.tmp / relative
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_text(text, encoding="utf-8")

    def write_json(self, relative: str, data) -> None:
        self.write_text(relative, json.dumps(data, indent=1))

    def __exit__(self, exc_type: type | None, exc: BaseException | None, tb: TracebackType | None) -> None:
        if exc_type is None:
            self.write_text("data.yaml", data_yaml_text())
            mark_output(self.tmp, DATASET)
        self._folder.__exit__(exc_type, exc, tb)


def _link_or_copy(source: Path, target: Path) -> None:
    try:
        os.symlink(source.resolve(), target)
    except OSError:  # a file system without links
        shutil.copyfile(source, target)


def data_yaml_text() -> str:
    """data.yaml as Roboflow writes it (paths relative to the yaml, canonical class order)."""
    return ("train: ../train/images\nval: ../valid/images\ntest: ../test/images\n\n"
            f"nc: {len(CLASSES)}\nnames: {list(CLASSES)}\n")


def write_dataset(out: str | Path, dataset: Dataset, *, force: bool = False) -> Path:
    """Copy a dataset's images and instances into a new Roboflow-layout folder; returns its path."""
    with DatasetWriter(out, force=force, protect=dataset.input_folders()) as writer:
        for sample in dataset.samples:
            if sample.image is not None:
                writer.add(sample.split, sample.image.name, sample.image, sample.instances)
    return writer.out
