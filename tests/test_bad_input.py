"""A corpus of bad input, built by code at test time, against every ``poles`` command.

Each case asserts: exit status 2, one message naming the file at fault, no traceback, the input unchanged (hashed)
and no output written. Valid oddities (BOM, CRLF, a PNG named .jpg, grey and 16-bit images, spelt-out and reordered
class names, COCO without sizes or with flat polygons, a foreign annotations.json) are accepted end to end.
"""
from __future__ import annotations

import errno
import hashlib
import json
import os
import shutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from detector.cli import main
from detector.datasets import load_dataset
from detector.outputs import OUTPUT_MARKER
from detector.synth.generate import SynthJob, generate_dataset
from detector.model_files import ROBOT_WEIGHTS


def tree_hash(root: Path) -> str:
    """Hash of every file's path and bytes under ``root``: equal before and after means nothing was touched."""
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*")):
        digest.update(str(path.relative_to(root)).encode())
        if path.is_file():
            digest.update(path.read_bytes())
    return digest.hexdigest()


def first_label(data: Path) -> Path:
    return next(p for p in sorted((data / "train" / "labels").glob("*.txt")) if p.read_text().strip())


def first_image(data: Path) -> Path:
    return sorted((data / "train" / "images").glob("*.jpg"))[0]


def set_yaml(data: Path, **changes) -> None:
    config = yaml.safe_load((data / "data.yaml").read_text())
    config.update(changes)
    (data / "data.yaml").write_text(yaml.safe_dump(config))


def append_line(data: Path, line: str) -> Path:
    label = first_label(data)
    label.write_text(label.read_text() + line + "\n")
    return label


def to_coco(data: Path, coco: Path) -> Path:
    """Write ``data`` as a Roboflow COCO export (pixel polygons, a placeholder category 0)."""
    dataset = load_dataset(data)
    categories = [{"id": 0, "name": "poles", "supercategory": "none"}] + \
        [{"id": i + 1, "name": c, "supercategory": "poles"} for i, c in enumerate(("bp", "gp", "yp", "pb", "pg", "py"))]
    ids = {c["name"]: c["id"] for c in categories}
    for split in ("train", "valid", "test"):
        folder = coco / split
        folder.mkdir(parents=True)
        images, annotations = [], []
        for index, sample in enumerate(dataset.split(split)):
            shutil.copyfile(sample.image, folder / sample.image.name)
            h, w = cv2.imread(str(sample.image)).shape[:2]
            images.append({"id": index, "file_name": sample.image.name, "width": w, "height": h})
            for inst in sample.instances:
                annotations.append({"id": len(annotations), "image_id": index, "category_id": ids[inst.cls],
                                    "segmentation": [inst.pixels(w, h).reshape(-1).round(2).tolist()]})
        (folder / "_annotations.coco.json").write_text(json.dumps(
            {"images": images, "annotations": annotations, "categories": categories}))
    return coco


def coco_edit(coco: Path, change: Callable[[dict], None]) -> Path:
    path = coco / "train" / "_annotations.coco.json"
    data = json.loads(path.read_text())
    change(data)
    path.write_text(json.dumps(data))
    return path


@dataclass
class Case:
    """A bad input: ``make(tmp, data)`` damages a copy of the dataset (or builds other input) and returns
    (argv, the folder that must stay unchanged, the text the message must hold)."""

    name: str
    make: Callable[[Path, Path], tuple[list[str], Path, str]]


def dataset_case(name: str, damage: Callable[[Path], object], command: str, named: str | None = None) -> Case:
    """A dataset damaged by ``damage`` run through ``command``; the message must name ``named`` (default: the file
    ``damage`` returned)."""

    def make(tmp: Path, data: Path):
        culprit = damage(data)
        return COMMAND_ARGV[command](tmp, data), data, named or Path(culprit).name

    return Case(f"{command}: {name}", make)


COMMAND_ARGV: dict[str, Callable[[Path, Path], list[str]]] = {
    "convert": lambda tmp, data: ["convert", str(data), "--out", str(tmp / "out")],
    "split": lambda tmp, data: ["split", "--data", str(data), "--out", str(tmp / "out")],
    "augment": lambda tmp, data: ["augment", "--data", str(data), "--out", str(tmp / "out"), "--copies", "1"],
    "train": lambda tmp, data: ["train", "--data", str(data), "--out", str(tmp / "out"), "--epochs", "1", "--imgsz", "64"],
    "evaluate": lambda tmp, data: ["evaluate", "--data", str(data), "--out", str(tmp / "out")],
    "calibrate": lambda tmp, data: ["calibrate", "--data", str(data), "--out", str(tmp / "out")],
    "export": lambda tmp, data: ["export", "--weights", str(tmp / "none.pt"), "--data", str(data),
                                 "--out", str(tmp / "out.onnx")],
}

DAMAGES: dict[str, Callable[[Path], object]] = {
    "class id inf": lambda d: append_line(d, "inf 0.1 0.1 0.2 0.1 0.2 0.2"),
    "class id nan": lambda d: append_line(d, "nan 0.1 0.1 0.2 0.1 0.2 0.2"),
    "class id out of range": lambda d: append_line(d, "9 0.1 0.1 0.2 0.1 0.2 0.2"),
    "odd coordinate count": lambda d: append_line(d, "0 0.1 0.1 0.2 0.1 0.2"),
    "bounding-box line": lambda d: append_line(d, "0 0.5 0.5 0.2 0.3"),
    "nan coordinate": lambda d: append_line(d, "0 0.1 nan 0.2 0.1 0.2 0.2"),
    "pixel coordinates": lambda d: append_line(d, "0 10 20 30 20 30 40"),
    "zero-byte image": lambda d: (first_image(d).write_bytes(b""), first_image(d))[1],
    "text named .jpg": lambda d: (first_image(d).write_text("not an image"), first_image(d))[1],
    "data.yaml is a list": lambda d: ((d / "data.yaml").write_text("- a\n- b\n"), d / "data.yaml")[1],
    "data.yaml is a scalar": lambda d: ((d / "data.yaml").write_text("42\n"), d / "data.yaml")[1],
    "data.yaml in latin-1": lambda d: ((d / "data.yaml").write_bytes("names: ['caf\xe9']\n".encode("latin-1")),
                                       d / "data.yaml")[1],
    "broken YAML": lambda d: ((d / "data.yaml").write_text("names: [bp, gp\ntrain: :\n"), d / "data.yaml")[1],
    "duplicate class names": lambda d: (set_yaml(d, names=["bp", "bp", "yp", "pb", "pg", "py"]), d / "data.yaml")[1],
    "unknown class name": lambda d: (set_yaml(d, names=["bp", "gp", "yp", "pb", "pg", "ball"]), d / "data.yaml")[1],
    "no names": lambda d: (set_yaml(d, names=None), d / "data.yaml")[1],
    "label without image": lambda d: ((d / "train" / "labels" / "orphan.txt").write_text(""),
                                      d / "train" / "labels" / "orphan.txt")[1],
    "binary label file": lambda d: (label := first_label(d), label.write_bytes(b"\xff\xfe\x00\x81"))[0],
    "path: names nowhere": lambda d: (set_yaml(d, path="../nowhere"), d / "data.yaml")[1],
}

#: Each damage meets several commands, spread so that every command sees several kinds.
ROTATION = ["convert", "split", "augment", "train", "evaluate", "calibrate"]
DATASET_CASES = [dataset_case(name, damage, ROTATION[(i + k) % len(ROTATION)])
                 for i, (name, damage) in enumerate(DAMAGES.items()) for k in (0, 3)]


def _coco_case(name: str, change: Callable[[dict], None], named: str, command: str = "convert") -> Case:
    def make(tmp: Path, data: Path):
        coco = to_coco(data, tmp / "coco")
        coco_edit(coco, change)
        return COMMAND_ARGV[command](tmp, coco), coco, named

    return Case(f"{command}: COCO {name}", make)


def _duplicate_id(d):
    d["images"][1]["id"] = d["images"][0]["id"]


def _halve_size(d):
    d["images"][0]["width"] //= 2


def _annotation(d):
    return next(a for a in d["annotations"])


COCO_CASES = [
    _coco_case("duplicate image id", _duplicate_id, "image id"),
    _coco_case("declared size differs", _halve_size, "is declared", "split"),
    _coco_case("nan coordinate", lambda d: _annotation(d)["segmentation"][0].__setitem__(1, float("nan")), "not finite",
               "augment"),
    _coco_case("unknown image_id", lambda d: _annotation(d).__setitem__("image_id", 999), "image_id 999", "train"),
    _coco_case("outlines of an unknown category", lambda d: (
        d["categories"].append({"id": 9, "name": "ball", "supercategory": "p"}),
        _annotation(d).__setitem__("category_id", 9)), "'ball' names no landmark and labels 1 outline", "evaluate"),
    _coco_case("box only", lambda d: _annotation(d).__setitem__("segmentation", []), "segmentation labels needed"),
    _coco_case("outside the image", lambda d: _annotation(d)["segmentation"][0].__setitem__(0, 5000.0),
               "outside the", "split"),
    _coco_case("segmentation is a string", lambda d: _annotation(d).__setitem__("segmentation", "x"), "not a list"),
    _coco_case("not a COCO file", lambda d: d.clear() or d.update({"images": "x"}), "_annotations.coco.json"),
]


def _coco_without_images(tmp: Path, data: Path):
    """A COCO export whose only JSON lists no image: refused as a YOLOv8 export without images is."""
    coco = to_coco(data, tmp / "coco")
    for split in ("valid", "test"):
        shutil.rmtree(coco / split)
    coco_edit(coco, lambda d: d.update(images=[], annotations=[]))
    return COMMAND_ARGV["evaluate"](tmp, coco), coco, "no images found in any split"


def _out_case(name: str, out: Callable[[Path, Path], Path], command: str, force: bool = True) -> Case:
    def make(tmp: Path, data: Path):
        argv = COMMAND_ARGV[command](tmp, data)
        target = out(tmp, data)
        argv[argv.index(str(tmp / "out"))] = str(target)
        return argv + (["--force"] if force else []), data, "overlaps the input" if target.is_dir() or not target.exists() \
            else target.name

    return Case(f"{command}: --out {name}", make)


def _moved_dataset(tmp: Path, data: Path) -> Path:
    """data.yaml whose ``path:`` names a sibling folder holding the splits; returns that folder."""
    store = tmp / "store"
    for split in ("train", "valid", "test"):
        shutil.move(str(data / split), str(store / split))
    set_yaml(data, path="../store")
    return store


OUTPUT_CASES = [
    _out_case("is the input", lambda tmp, d: d, "augment"),
    _out_case("inside the images folder", lambda tmp, d: d / "train" / "images" / "new", "convert", force=False),
    _out_case("is the folder path: names", _moved_dataset, "augment"),
    _out_case("contains the input", lambda tmp, d: d.parent, "split"),
    _out_case("is an existing file", lambda tmp, d: (tmp / "file.txt", (tmp / "file.txt").write_text("x"))[0], "convert",
              force=False),
    _out_case("is the input", lambda tmp, d: d, "evaluate"),
    _out_case("inside the images folder", lambda tmp, d: d / "train" / "images", "evaluate"),
    _out_case("is the dataset's data.yaml", lambda tmp, d: d / "data.yaml", "calibrate"),
]


def _plain(name: str, build: Callable[[Path, Path], tuple[list[str], Path, str]]) -> Case:
    return Case(name, build)


def _truth_csv(tmp: Path, rows: str) -> Path:
    path = tmp / "ranges.csv"
    path.write_text(rows)
    return path


def _calibrate_truth(row: str, named: str) -> Callable:
    def build(tmp: Path, data: Path):
        name = first_image(data).name
        cls = load_dataset(data).split("train")[0].instances
        code = cls[0].cls if cls else "bp"
        csv_path = _truth_csv(tmp, "image,class,range_m\n" + row.format(image=name, cls=code) + "\n")
        return ["calibrate", "--data", str(data), "--truth", str(csv_path), "--out", str(tmp / "out")], tmp, named

    return build


def _calibrate_at_one_range(tmp: Path, data: Path):
    """`poles calibrate --truth` whose rows put every pole at 2 m (one row per image's only pole of a class)."""
    rows = []
    for sample in load_dataset(data).samples:
        classes = [i.cls for i in sample.instances]
        rows += [f"{sample.image.name},{cls},2.0" for cls in dict.fromkeys(classes) if classes.count(cls) == 1]
    csv_path = _truth_csv(tmp, "image,class,range_m\n" + "\n".join(rows) + "\n")
    return (["calibrate", "--data", str(data), "--truth", str(csv_path), "--out", str(tmp / "out")], tmp,
            "ranges.csv: every pole measured stands at 2 m")


def _annotations_with_range(value: float) -> Callable:
    """`poles calibrate` on a dataset whose annotations.json gives one landmark the range ``value``."""
    def build(tmp: Path, data: Path):
        path = data / "annotations.json"
        annotations = json.loads(path.read_text())
        landmark = next(lm for entry in annotations["images"].values() for lm in entry["landmarks"])
        landmark["range_m"] = value
        path.write_text(json.dumps(annotations))  # json writes NaN and Infinity, as another tool might
        return ["calibrate", "--data", str(data), "--out", str(tmp / "out")], data, "annotations.json: "

    return build


def _annotations_of_another_shape(tmp: Path, data: Path):
    """`poles calibrate` on a dataset whose annotations.json is a list, not ``images`` -> ``landmarks``."""
    (data / "annotations.json").write_text(json.dumps([{"file": "a.jpg", "distance": 2.0}]))
    return ["calibrate", "--data", str(data), "--out", str(tmp / "out")], data, "annotations.json: no landmark in it"


def _detection_checkpoint(tmp: Path) -> Path:
    """An untrained YOLOv8n *detection* checkpoint, as Ultralytics saves one: boxes, no masks."""
    import torch
    from ultralytics.nn.tasks import DetectionModel, yaml_model_load

    path = tmp / "inputs" / "detect.pt"
    path.parent.mkdir(exist_ok=True)
    config = {**yaml_model_load("yolov8n.yaml"), "nc": 6}  # nc in the config: Ultralytics logs no override
    torch.save({"model": DetectionModel(config, verbose=False).half(), "train_args": {"task": "detect"}, "epoch": -1},
               path)
    return path


def _calibration_with_law(tmp: Path, a: float) -> Path:
    """A calibration.json whose width law is ``a * px ** -1``: as `poles calibrate` writes it, the number aside."""
    from naoslam.measurement import PowerLaw, RangeCalibration

    data = RangeCalibration(PowerLaw(60.0, -1.0, 0.1), PowerLaw(200.0, -1.0, 0.1)).to_dict()
    data["width_law"]["a"] = a
    path = tmp / "inputs" / "c.json"
    path.parent.mkdir(exist_ok=True)
    path.write_text(json.dumps({"calibration": data}))
    return path


def _empty_file(tmp: Path, name: str) -> Path:
    path = tmp / "inputs" / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(b"")
    return path


def _garbage(tmp: Path, name: str) -> Path:
    path = tmp / "inputs" / name
    path.parent.mkdir(exist_ok=True)
    path.write_bytes(b"\x00garbage\xff" * 50)
    return path


def _utias(tmp: Path, utias: Path, edit: Callable[[Path], None],
           named: str = "Odometry.dat") -> tuple[list[str], Path, str]:
    folder = tmp / "inputs" / "utias"
    shutil.copytree(utias, folder)
    edit(folder)
    return ["slam", "--utias", str(folder), "--duration", "20", "--out", str(tmp / "out")], folder, named


def _odometry(tmp: Path, rows: str, frame: str | None = None) -> tuple[list[str], Path, str]:
    """A recording whose odometry CSV holds ``rows``, with one black frame file named ``frame`` (the file the
    message must name) or none (the CSV must be named)."""
    folder = tmp / "inputs"
    (folder / "frames").mkdir(parents=True)
    (folder / "odo.csv").write_text(rows)
    if frame:
        cv2.imwrite(str(folder / "frames" / frame), np.zeros((48, 64, 3), np.uint8))
    return ["slam", "--frames", str(folder / "frames"), "--odometry", str(folder / "odo.csv"),
            "--frontend", "colour-filter", "--out", str(tmp / "out")], folder, frame or "odo.csv"


def _undecodable_frame(tmp: Path) -> tuple[list[str], Path, str]:
    """A recording whose one frame is the first bytes of a JPEG the robot never finished writing."""
    argv, folder, frame = _odometry(tmp, "t,x,y,theta\n0,0,0,0\n1,1,0,0\n", frame="0.5.jpg")
    (folder / "frames" / frame).write_bytes(b"\xff\xd8\xff")
    return argv, folder, frame


def _slam_into_the_recording(tmp: Path) -> tuple[list[str], Path, str]:
    """``--out --force`` naming the folder that holds the recording's frames and odometry."""
    argv, folder, _ = _odometry(tmp, "t,x,y,theta\n0,0,0,0\n1,1,0,0\n", frame="0.5.jpg")
    argv[argv.index(str(tmp / "out"))] = str(folder)
    return argv + ["--force"], folder, "overlaps the input"


def _plot_over_a_frame(tmp: Path, data: Path) -> tuple[list[str], Path, str]:
    """``poles calibrate --plot --force`` naming a PNG beside the dataset's own frames."""
    frame = first_image(data)
    return (COMMAND_ARGV["calibrate"](tmp, data) + ["--plot", str(frame.with_suffix(".png")), "--force"], data,
            "overlaps the input")


def _synth_into_the_backgrounds(tmp: Path) -> tuple[list[str], Path, str]:
    """``poles synth --out`` inside ``--backgrounds``: its frames with poles would be read back as frames without."""
    folder = tmp / "inputs" / "backgrounds"
    folder.mkdir(parents=True)
    cv2.imwrite(str(folder / "office.jpg"), np.full((240, 320, 3), 120, np.uint8))
    return ["synth", "--out", str(folder / "synth"), "--images", "2", "--backgrounds", str(folder)], folder, \
        "overlaps the input"


def _video(tmp: Path) -> Path:
    """A three-frame MP4 in ``tmp/inputs``."""
    path = tmp / "inputs" / "walk.mp4"
    path.parent.mkdir(exist_ok=True)
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 5, (64, 48))
    for _ in range(3):
        writer.write(np.zeros((48, 64, 3), np.uint8))
    writer.release()
    return path


def _video_onto_itself(tmp: Path) -> tuple[list[str], Path, str]:
    video = _video(tmp)
    return ["predict", "--video", str(video), "--out", str(video), "--force"], video.parent, "overlaps the input"


def _sheet_name_taken(tmp: Path) -> tuple[list[str], Path, str]:
    """The contact sheet ``OUT.png`` would replace a file already there."""
    video = _video(tmp)
    (tmp / "overlay.png").write_bytes(b"someone's picture")
    return ["predict", "--video", str(video), "--out", str(tmp / "overlay.mp4")], tmp, "overlay.png"


def _roboflow_zip(tmp: Path, data: Path) -> tuple[list[str], Path, str]:
    """The archive Roboflow downloads, given where its unzipped folder belongs."""
    archive = Path(shutil.make_archive(str(tmp / "inputs" / "poles.v1i.yolov8"), "zip", data))
    return ["train", str(archive), "--out", str(tmp / "out"), "--epochs", "1", "--imgsz", "64"], archive.parent, \
        "unzip poles.v1i.yolov8.zip -d poles.v1i.yolov8"


def _swap_odometry_rows(folder: Path) -> None:
    path = folder / "Odometry.dat"
    lines = path.read_text().splitlines()
    data = [i for i, line in enumerate(lines) if line.strip() and not line.startswith("#")]
    lines[data[5]], lines[data[6]] = lines[data[6]], lines[data[5]]
    path.write_text("\n".join(lines) + "\n")


def _poison_odometry(folder: Path, value: str) -> None:
    path = folder / "Odometry.dat"
    lines = path.read_text().splitlines()
    index = next(i for i, line in enumerate(lines) if line.strip() and not line.startswith("#"))
    parts = lines[index].split()
    lines[index + 3] = " ".join([parts[0], value, parts[2]])
    path.write_text("\n".join(lines) + "\n")


def _header_only(path: Path) -> None:
    path.write_text("".join(line for line in path.read_text().splitlines(keepends=True) if line.startswith("#")))


def _empty_odometry(folder: Path) -> None:
    (folder / "Odometry.dat").write_text("# Time [s]    forward velocity [m/s]    angular velocity[rad/s]\n")


OTHER_CASES = [
    _plain("synth: --hfov 0", lambda tmp, d: (["synth", "--out", str(tmp / "out"), "--images", "2", "--hfov", "0"], tmp,
                                               "--hfov")),
    _plain("synth: --images 0", lambda tmp, d: (["synth", "--out", str(tmp / "out"), "--images", "0"], tmp, "--images")),
    _plain("synth: backgrounds folder missing", lambda tmp, d: (["synth", "--out", str(tmp / "out"), "--images", "2",
                                                                 "--backgrounds", str(tmp / "none")], tmp, "none")),
    _plain("synth: --out inside the backgrounds folder", lambda tmp, d: _synth_into_the_backgrounds(tmp)),
    _plain("augment: config is broken YAML", lambda tmp, d: (
        COMMAND_ARGV["augment"](tmp, d) + ["--config", str(_truth_csv(tmp, "rotate_deg: [1\n"))], d, "ranges.csv")),
    _plain("augment: config has an unknown key", lambda tmp, d: (
        COMMAND_ARGV["augment"](tmp, d) + ["--config", str(_truth_csv(tmp, "spin: 3\n"))], d, "unknown setting")),
    _plain("augment: config value of the wrong type", lambda tmp, d: (
        COMMAND_ARGV["augment"](tmp, d) + ["--config", str(_truth_csv(tmp, "rotate_deg: abc\n"))], d,
        "ranges.csv: augmentation setting rotate_deg = 'abc' is not a number")),
    _plain("augment: config value out of range", lambda tmp, d: (
        COMMAND_ARGV["augment"](tmp, d) + ["--config", str(_truth_csv(tmp, "rotate_deg: 500\n"))], d,
        "ranges.csv: augmentation setting rotate_deg = 500 is outside")),
    _plain("export: garbage .pt", lambda tmp, d: (["export", "--weights", str(_garbage(tmp, "best.pt")), "--data", str(d),
                                                   "--out", str(tmp / "out" / "m.onnx")], tmp / "inputs", "best.pt")),
    _plain("export: negative --imgsz", lambda tmp, d: (COMMAND_ARGV["export"](tmp, d) + ["--imgsz", "96", "-128"], d,
                                                        "--imgsz")),
    _plain("export: missing .pt", lambda tmp, d: (COMMAND_ARGV["export"](tmp, d), d, "none.pt")),
    _plain("train: --weights garbage", lambda tmp, d: (COMMAND_ARGV["train"](tmp, d) + ["--weights",
                                                       str(_garbage(tmp, "w.pt"))], tmp / "inputs", "w.pt")),
    _plain("train: --resume without a run", lambda tmp, d: (["train", "--data", str(d), "--out", str(tmp / "out"),
                                                             "--resume"], d, "nothing to resume")),
    _plain("evaluate: garbage .onnx", lambda tmp, d: (["evaluate", "--model", str(_garbage(tmp, "m.onnx")), "--data",
                                                       str(d), "--out", str(tmp / "out")], tmp / "inputs", "m.onnx")),
    _plain("evaluate: garbage .pt", lambda tmp, d: (["evaluate", "--model", str(_garbage(tmp, "best.pt")), "--data",
                                                     str(d), "--out", str(tmp / "out")], tmp / "inputs", "best.pt")),
    _plain("evaluate: empty .pt", lambda tmp, d: (["evaluate", "--model", str(_empty_file(tmp, "last.pt")), "--data",
                                                   str(d), "--out", str(tmp / "out")], tmp / "inputs", "last.pt")),
    _plain("evaluate: a detection checkpoint", lambda tmp, d: (
        ["evaluate", str(d), "--model", str(_detection_checkpoint(tmp)), "--out", str(tmp / "out")], tmp / "inputs",
        "detect.pt: a detect model, not a segmentation model")),
    _plain("evaluate: garbage --calibration", lambda tmp, d: (
        ["evaluate", str(d), "--model", "colour-filter", "--calibration", str(_garbage(tmp, "c.json")), "--out",
         str(tmp / "out")], tmp / "inputs", "c.json")),
    _plain("slam: --calibration with a negative range law", lambda tmp, d: (
        ["slam", "--sim", "square", "--frontend", "colour-filter", "--calibration",
         str(_calibration_with_law(tmp, -60.0)), "--out", str(tmp / "out")], tmp / "inputs",
        "c.json: not a calibration")),
    _plain("slam: --calibration with a NaN range law", lambda tmp, d: (
        ["slam", "--sim", "square", "--frontend", "colour-filter", "--calibration",
         str(_calibration_with_law(tmp, float("nan"))), "--out", str(tmp / "out")], tmp / "inputs",
        "a must be above 0")),
    _plain("evaluate: --calibration of another kind", lambda tmp, d: (
        ["evaluate", str(d), "--model", "colour-filter", "--calibration", str(_truth_csv(tmp, '{"a": 1}')), "--out",
         str(tmp / "out")], tmp, "ranges.csv: not a calibration")),
    _plain("slam: missing --calibration", lambda tmp, d: (
        ["slam", "--sim", "square", "--calibration", str(tmp / "none.json"), "--out", str(tmp / "out")], tmp,
        "none.json: no such calibration file")),
    _plain("evaluate: COCO without images", _coco_without_images),
    _plain("evaluate: a split without images", lambda tmp, d: (
        (shutil.rmtree(d / "test"), ["evaluate", str(d), "--split", "test", "--out", str(tmp / "out")])[1], d,
        "pick another with --split: train (")),
    _plain("evaluate: unknown model kind", lambda tmp, d: (["evaluate", "--model", "model.h5", "--data", str(d),
                                                            "--out", str(tmp / "out")], d, "model.h5")),
    _plain("calibrate: --plot not a PNG", lambda tmp, d: (
        ["calibrate", "--data", str(d), "--out", str(tmp / "out"), "--plot", str(tmp / "fit.txt")], d,
        "name it *.png")),
    _plain("calibrate: range inf", _calibrate_truth("{image},{cls},inf", "ranges.csv:2")),
    _plain("calibrate: annotations.json with a NaN range", _annotations_with_range(float("nan"))),
    _plain("calibrate: annotations.json with a negative range", _annotations_with_range(-2.0)),
    _plain("calibrate: annotations.json of another shape", _annotations_of_another_shape),
    _plain("calibrate: range 0", _calibrate_truth("{image},{cls},0", "ranges.csv:2")),
    _plain("calibrate: every pole at one range", _calibrate_at_one_range),
    _plain("calibrate: range not a number", _calibrate_truth("{image},{cls},far", "ranges.csv:2")),
    _plain("calibrate: unknown class", _calibrate_truth("{image},ball,1.0", "ranges.csv:2")),
    _plain("calibrate: a row without its range", _calibrate_truth("{image}", "ranges.csv:2: no value for class, "
                                                                             "range_m")),
    _plain("slam: odometry CSV with an empty value", lambda tmp, d: _odometry(tmp, "t,x,y,theta\n0,0,0,0\n1,1,,0\n")),
    _plain("calibrate: --embed into garbage", lambda tmp, d: (
        ["calibrate", "--data", str(d), "--out", str(tmp / "out"), "--embed", str(_garbage(tmp, "m.onnx"))],
        tmp / "inputs", "m.onnx")),
    _plain("slam: odometry CSV with nan", lambda tmp, d: _odometry(tmp, "t,x,y,theta\n0,0,0,0\n1,nan,0,0\n")),
    _plain("slam: odometry CSV without header", lambda tmp, d: _odometry(tmp, "0,0,0,0\n1,1,0,0\n")),
    _plain("slam: odometry CSV with one row", lambda tmp, d: _odometry(tmp, "t,x,y,theta\n0,0,0,0\n")),
    _plain("slam: frames without odometry", lambda tmp, d: (["slam", "--frames", str(tmp), "--out", str(tmp / "out")],
                                                            d, "--odometry")),
    _plain("slam: odometry CSV with unsorted times", lambda tmp, d: _odometry(tmp, "t,x,y,theta\n0,0,0,0\n2,1,0,0\n"
                                                                                  "1,2,0,0\n")),
    _plain("slam: odometry CSV empty", lambda tmp, d: _odometry(tmp, "")),
    _plain("slam: frame after the odometry ends", lambda tmp, d: _odometry(tmp, "t,x,y,theta\n0,0,0,0\n1,1,0,0\n",
                                                                           frame="50.0.jpg")),
    _plain("slam: frame not named by its time", lambda tmp, d: _odometry(tmp, "t,x,y,theta\n0,0,0,0\n1,1,0,0\n",
                                                                         frame="left.jpg")),
    _plain("slam: a frame that cannot be decoded", lambda tmp, d: _undecodable_frame(tmp)),
    _plain("slam: --out is the recording's folder", lambda tmp, d: _slam_into_the_recording(tmp)),
    _plain("calibrate: --plot among the dataset's frames", _plot_over_a_frame),
    _plain("train: the Roboflow zip, not its folder", _roboflow_zip),
    _plain("predict: --out is the input video", lambda tmp, d: _video_onto_itself(tmp)),
    _plain("predict: the contact sheet's name is taken", lambda tmp, d: _sheet_name_taken(tmp)),
    _plain("slam: --confusion-rate above 1", lambda tmp, d: (["slam", "--sim", "square", "--confusion-rate", "2",
                                                              "--out", str(tmp / "out")], tmp, "--confusion-rate")),
    _plain("convert: --out under a file", lambda tmp, d: (
        ["convert", str(d), "--out", str(_garbage(tmp, "notes.txt") / "copy")], tmp / "inputs",
        "notes.txt is a file, so nothing can be written under it")),
    _plain("slam: negative --lookalikes", lambda tmp, d: (["slam", "--sim", "square", "--lookalikes", "-1",
                                                           "--out", str(tmp / "out")], tmp, "--lookalikes")),
]


def _utias_case(name: str, edit: Callable[[Path], None], named: str = "Odometry.dat") -> Case:
    def make(tmp: Path, data: Path):
        from tests.conftest import SHARED

        utias = SHARED / "utias-mrclam" / "dataset0"
        if not (utias / "Odometry.dat").is_file():
            pytest.skip("../shared/utias-mrclam is not on this machine")
        return _utias(tmp, utias, edit, named)

    return Case(f"slam: UTIAS {name}", make)


UTIAS_CASES = [
    _utias_case("unsorted time stamps", _swap_odometry_rows),
    _utias_case("nan in odometry", lambda f: _poison_odometry(f, "nan")),
    _utias_case("inf in odometry", lambda f: _poison_odometry(f, "inf")),
    _utias_case("binary odometry", lambda f: (f / "Odometry.dat").write_bytes(b"\x00\xff\xfe" * 100)),
    _utias_case("empty odometry", _empty_odometry),
    *[_utias_case(f"{name} with only its header", lambda f, name=name: _header_only(f / name), named=name)
      for name in ("Measurement.dat", "Landmark_Groundtruth.dat")],
]

CASES = DATASET_CASES + COCO_CASES + OUTPUT_CASES + OTHER_CASES + UTIAS_CASES


def test_the_corpus_is_large_enough():
    assert len(CASES) >= 60
    assert {c.name.split(":")[0] for c in CASES} >= {"convert", "split", "augment", "train", "evaluate", "calibrate",
                                                      "export", "slam", "synth"}


@pytest.mark.parametrize("case", CASES, ids=lambda c: c.name)
def test_bad_input_is_refused_clearly_and_nothing_changes(case, dataset_copy, tmp_path, capsys):
    argv, guarded, named = case.make(tmp_path, dataset_copy)
    before = tree_hash(guarded)
    outputs_before = {p for p in tmp_path.iterdir()}
    status = main(argv)
    error = capsys.readouterr().err
    assert status == 2, error
    assert named in error, error
    assert "Traceback" not in error and "unexpected error" not in error
    assert len(error.strip().splitlines()) <= 25
    assert tree_hash(guarded) == before
    assert not (tmp_path / "out").exists() and not list(tmp_path.glob(".out*"))
    new = {p for p in tmp_path.iterdir()} - outputs_before
    assert not new, new


@pytest.mark.parametrize("signal_name, status", [("SIGTERM", 143), ("SIGINT", 130)])
def test_an_interrupted_command_leaves_nothing_and_says_one_line(signal_name, status, tmp_path):
    import signal
    import subprocess
    import sys
    import time

    out = tmp_path / "out"
    process = subprocess.Popen([sys.executable, "-c", "import sys; from detector.cli import main; sys.exit(main())",
                                "synth", "--out", str(out), "--images", "5000", "--workers", "1", "--size", "160x120"],
                               stderr=subprocess.PIPE, text=True,
                               # as from a terminal: a runner started in the background ignores SIGINT, and a child
                               # would inherit that (Python keeps an inherited SIG_IGN)
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.time() + 60
    while not list(tmp_path.glob(".out.partial-*")) and time.time() < deadline:
        time.sleep(0.2)
    time.sleep(1.0)
    process.send_signal(getattr(signal, signal_name))
    _, error = process.communicate(timeout=60)
    assert process.returncode == status, error
    lines = [line for line in error.splitlines() if line.strip() and "rendering" not in line]
    assert len(lines) == 1 and "Traceback" not in error, error
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("argv", [["slam", "--sim", "square", "--out", "{tmp}/out", "--duration", "nan"],
                                  ["slam", "--sim", "square", "--out", "{tmp}/out", "--duration", "inf"],
                                  ["slam", "--sim", "square", "--out", "{tmp}/out", "--odometry-bias", "nan"],
                                  ["slam", "--sim", "square", "--out", "{tmp}/out", "--min-separation", "nan"],
                                  ["slam", "--frames", "{tmp}", "--out", "{tmp}/out", "--time-offset", "nan"],
                                  ["train", "{tmp}", "--out", "{tmp}/out", "--time", "nan"],
                                  ["split", "{tmp}", "--out", "{tmp}/out", "--ratios", "0.7", "nan", "0.1"],
                                  ["synth", "--out", "{tmp}/out", "--hfov", "inf"]])
def test_a_number_that_is_not_finite_is_refused_before_anything_runs(argv, tmp_path, capsys):
    """``float`` reads nan and inf: --duration inf ended in an OverflowError, --time nan after a trained epoch."""
    with pytest.raises(SystemExit) as exited:
        main([a.format(tmp=tmp_path) for a in argv])
    assert exited.value.code == 2
    assert "is not a finite number" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("argv", [["finetune", "{tmp}", "--out", "{tmp}/out", "--minutes", "1e308"],
                                  ["demo", "--out", "{tmp}/out", "--minutes", "20000"],
                                  ["train-robot", "{tmp}", "--out", "{tmp}/out", "--minutes", "1e308"]])
def test_a_time_budget_beyond_a_week_is_refused_before_anything_runs(argv, tmp_path, capsys):
    """``--minutes 1e308`` once ran, and its plan's arithmetic wrote ``Infinity`` into stages.json and metrics.json."""
    with pytest.raises(SystemExit) as exited:
        main([a.format(tmp=tmp_path) for a in argv])
    assert exited.value.code == 2
    assert "give at most 10080 minutes (a week)" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("argv", [["predict", "--images", "{tmp}", "--out", "{tmp}/out", "--conf", "-1"],
                                  ["evaluate", "{tmp}", "--out", "{tmp}/out", "--conf", "2"],
                                  ["slam", "--sim", "square", "--out", "{tmp}/out", "--conf", "1.5"],
                                  ["export", "--weights", "w.pt", "--out", "{tmp}/m.onnx", "--conf", "0"],
                                  ["synth", "--out", "{tmp}/out", "--workers", "-3"],
                                  ["augment", "{tmp}", "--out", "{tmp}/out", "--workers", "two"],
                                  ["split", "--data", "{tmp}", "--out", "{tmp}/out", "--seed", "-1"],
                                  ["slam", "--sim", "square", "--out", "{tmp}/out", "--compare", "-2"],
                                  ["train", "{tmp}", "--out", "{tmp}/out", "--patience", "-1"],
                                  ["train", "{tmp}", "--out", "{tmp}/out", "--batch", "0"]])
def test_a_threshold_or_process_count_out_of_range_is_refused_before_anything_runs(argv, tmp_path, capsys):
    """A --conf of -1 pre-labelled every candidate box (4,162 'poles' on 14 frames), one of 5 made SLAM run blind."""
    with pytest.raises(SystemExit) as exited:
        main([a.format(tmp=tmp_path) for a in argv])
    assert exited.value.code == 2
    error = capsys.readouterr().err
    assert "between 0 and 1" in error or "or more" in error or "whole number" in error, error
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("code, fix", [(errno.ENOSPC, "the disk is full"), (errno.EACCES, "permission denied"),
                                       (errno.ENOTDIR, "a file stands where a folder is needed")])
def test_an_operating_system_refusal_names_the_users_path_and_the_fix(code, fix):
    """An atomic writer's temporary folder is hidden from the user: the message names the output it stands for."""
    from detector.errors import os_error_message

    error = OSError(code, os.strerror(code), "/robot/runs/.data.partial-x1y2/train/images/a.jpg")
    assert os_error_message(error).startswith(f"/robot/runs/data: {fix}")
    assert os_error_message(OSError(code, os.strerror(code), "/robot/runs/plain.json")).startswith(
        f"/robot/runs/plain.json: {fix}")
    assert os_error_message(FileNotFoundError("model.onnx: no such model file")) == "model.onnx: no such model file"


@pytest.mark.parametrize("command", ["synth", "convert"])
def test_force_replaces_an_earlier_output_but_never_a_folder_of_the_users_own(command, dataset_copy, tmp_path, capsys):
    """``--out X --force`` onto a dataset of the user's (no marker): refused, X unchanged; onto the command's own
    earlier output: replaced."""
    argv = {"synth": ["synth", "--images", "2", "--workers", "1"], "convert": ["convert", str(dataset_copy)]}[command]
    users = Path(shutil.copytree(dataset_copy, tmp_path / "mydocs"))
    (users / OUTPUT_MARKER).unlink()  # rendered here, but a user's own from now on
    before = tree_hash(users)
    assert main(argv + ["--out", str(users), "--force"]) == 2
    err = capsys.readouterr().err
    assert str(users) in err and "did not write" in err and "Traceback" not in err
    assert tree_hash(users) == before
    earlier = tmp_path / "earlier"
    assert main(argv + ["--out", str(earlier)]) == 0
    assert main(argv + ["--out", str(earlier), "--force"]) == 0


def test_an_export_one_folder_down_is_pointed_at(dataset_copy, tmp_path, capsys):
    """An unzipped export often sits one folder below the folder given: the refusal names the one that holds it."""
    parent = tmp_path / "download"
    parent.mkdir()
    shutil.move(str(dataset_copy), parent / "poles-v3")
    assert main(["check", str(parent)]) == 1
    out = capsys.readouterr().out
    assert "one folder down" in out and str(parent / "poles-v3") in out


def test_the_rename_advice_leads_a_flood_of_per_line_errors(dataset_copy, capsys):
    """Thousands of broken lines once hid the one line that matters: a class that names no pole, and --rename."""
    set_yaml(dataset_copy, names=["ball", "gp", "yp", "pb", "pg", "py"])
    for label in sorted((dataset_copy / "train" / "labels").glob("*.txt")):
        label.write_text(label.read_text() + "".join("7 0.1 0.1 0.2\n" for _ in range(5)))
    first, *rest = _refusal_lines(["split", str(dataset_copy), "--out", str(dataset_copy.parent / "out")], capsys)
    assert "--rename" in first and "'ball'" in first, first
    assert "`poles finetune`" in first and "poles convert DATA --out NEW --rename 'ball=CODE'" in first, first
    assert any("x " in line and "class id 7" in line for line in rest), rest


def _refusal_lines(argv: list[str], capsys) -> list[str]:
    """The lines of a refusal from its "poles CMD:" line on (progress bars before it left out)."""
    assert main(argv) == 2
    lines = capsys.readouterr().err.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith(f"poles {argv[0]}:"))
    return lines[start:]


def test_a_short_names_list_is_named_before_the_lines_it_breaks(dataset_copy, capsys):
    """Labels that use class ids `names` leaves out: data.yaml is the cause, named first, the lines grouped after."""
    set_yaml(dataset_copy, names=["bp"], nc=6)
    lines = _refusal_lines(["convert", str(dataset_copy), "--out", str(dataset_copy.parent / "out")], capsys)
    assert "data.yaml" in lines[0] and "`names` lists 1 class(es) (nc: 6)" in lines[0], lines[0]
    assert "list every class" in lines[0]
    assert any("x " in line and "out of range" in line for line in lines[1:]), lines
    assert len(lines) <= 10 and "--fix" not in lines[-1], lines


def test_check_prints_the_cause_before_the_lines_it_explains(dataset_copy, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    set_yaml(dataset_copy, names=["bp"], nc=6)
    assert main(["check", str(dataset_copy)]) == 1
    out = capsys.readouterr().out
    kinds = [line for line in out.splitlines() if " x error:" in line]
    assert "`names` lists 1 class(es)" in kinds[0], kinds


def test_a_broken_path_is_the_first_line_of_the_refusal(dataset_copy, capsys):
    set_yaml(dataset_copy, path="../nowhere")
    lines = _refusal_lines(["split", str(dataset_copy), "--out", str(dataset_copy.parent / "out")], capsys)
    assert "path: '../nowhere' names no folder" in lines[0] and "delete the `path:` line" in lines[0], lines


def test_a_refusal_check_fix_cannot_clear_does_not_suggest_it(dataset_copy, tmp_path, capsys):
    for label in sorted((dataset_copy / "train" / "labels").glob("*.txt")):
        label.write_text("0 0.5 0.5 0.2 0.3\n")
    lines = _refusal_lines(["check", str(dataset_copy), "--fix", "--out", str(tmp_path / "clean")], capsys)
    assert "box" in lines[0] and not any("--fix --out CLEAN" in line for line in lines), lines
    lines = _refusal_lines(["split", str(dataset_copy), "--out", str(tmp_path / "out")], capsys)
    assert "box" in lines[0] and not any("--fix" in line for line in lines), lines


def test_a_refusal_check_fix_clears_suggests_it(dataset_copy, tmp_path, capsys):
    append_line(dataset_copy, "0 0.1 nan 0.2 0.1 0.2 0.2")
    lines = _refusal_lines(["split", str(dataset_copy), "--out", str(tmp_path / "out")], capsys)
    assert "not finite" in lines[0] and "`poles check DATA --fix --out CLEAN`" in lines[-1], lines


def test_a_coco_export_of_boxes_is_told_it_has_boxes_whatever_its_classes(dataset_copy, tmp_path, monkeypatch,
                                                                           capsys):
    """Roboflow's COCO detection export: `segmentation: []` on every annotation, a class that is no pole."""
    monkeypatch.chdir(tmp_path)
    coco = to_coco(dataset_copy, tmp_path / "coco")
    for split in ("train", "valid", "test"):
        path = coco / split / "_annotations.coco.json"
        data = json.loads(path.read_text())
        data["categories"] = [{"id": 0, "name": "leaves", "supercategory": "none"},
                              {"id": 1, "name": "Spot", "supercategory": "leaves"}]
        for annotation in data["annotations"]:
            annotation.update(category_id=1, segmentation=[], bbox=[1, 2, 3, 4])
        path.write_text(json.dumps(data))
    before = tree_hash(coco)
    assert main(["check", str(coco)]) == 1
    out = capsys.readouterr().out
    assert "box without a polygon" in next(line for line in out.splitlines() if " x error:" in line)
    assert "Spot=CODE" not in out
    train = load_dataset(coco).split("train")
    assert all(sample.boxes and not sample.instances for sample in train if sample.unread)  # the box-only column
    assert sum(1 for sample in train if sample.boxes) > 0
    lines = _refusal_lines(["convert", str(coco), "--out", str(tmp_path / "out")], capsys)
    assert "box without a polygon" in lines[0] and "instance segmentation" in lines[0], lines
    assert tree_hash(coco) == before


def test_a_coco_class_is_named_by_its_category_id_and_counts_only_read_images(dataset_copy, tmp_path, monkeypatch,
                                                                              capsys):
    monkeypatch.chdir(tmp_path)
    coco = to_coco(dataset_copy, tmp_path / "coco")
    path = coco / "train" / "_annotations.coco.json"
    data = json.loads(path.read_text())
    data["categories"][1]["name"] = "midrib"  # id 1, index 0 once the placeholder is skipped
    used = sum(a["category_id"] == 1 for a in data["annotations"])
    moved = next(image for image in data["images"]
                 if any(a["image_id"] == image["id"] and a["category_id"] == 1 for a in data["annotations"]))
    in_moved = sum(a["category_id"] == 1 and a["image_id"] == moved["id"] for a in data["annotations"])
    path.write_text(json.dumps(data))
    (coco / "valid" / "images").mkdir()
    shutil.move(coco / "train" / moved["file_name"], coco / "valid" / "images" / moved["file_name"])
    assert main(["check", str(coco)]) == 1
    out = " ".join(capsys.readouterr().out.split())
    assert f"category 1 'midrib' names no landmark and labels {used - in_moved} outline(s)" in out, out
    assert f"listed but missing beside it (it is in {coco / 'valid' / 'images'})" in out, out


@pytest.mark.parametrize("damage", ["class id out of range", "duplicate class names", "pixel coordinates",
                                    "unknown class name", "bounding-box line", "zero-byte image"])
def test_train_robot_refuses_what_check_refuses_in_the_same_words(damage, dataset_copy, tmp_path, capsys):
    DAMAGES[damage](dataset_copy)
    before = tree_hash(dataset_copy)
    converted = _refusal_lines(["convert", str(dataset_copy), "--out", str(tmp_path / "copy")], capsys)
    trained = _refusal_lines(["train-robot", str(dataset_copy), "--out", str(tmp_path / "robot"), "--epochs", "1",
                              "--threads", "1"], capsys)
    assert trained[0].split(":", 1)[1] == converted[0].split(":", 1)[1], (trained[0], converted[0])
    assert not (tmp_path / "robot").exists() and tree_hash(dataset_copy) == before


def test_train_robot_reads_the_truth_before_it_trains(synth_dataset, tmp_path, capsys, monkeypatch):
    """An annotations.json whose landmarks do not follow the labels is refused before any crop is cut."""
    import detector.robot_training

    data = Path(shutil.copytree(synth_dataset, tmp_path / "data"))
    annotations = json.loads((data / "annotations.json").read_text())
    entry = next(e for e in annotations["images"].values() if e.get("landmarks"))
    entry["landmarks"][0]["cls"] = "none"
    (data / "annotations.json").write_text(json.dumps(annotations))
    monkeypatch.setattr(detector.robot_training, "crop_sets", lambda *a, **k: pytest.fail("cropped before refusing"))
    lines = _refusal_lines(["train-robot", str(data), "--out", str(tmp_path / "robot")], capsys)
    assert "annotations.json" in lines[0] and "do not follow its label file" in lines[0], lines


def test_train_robot_writes_no_model_that_finds_no_valid_pole(synth_dataset, tmp_path):
    from detector.crops.settings import CropTrainSettings
    from detector.robot_training import train_robot_front_end

    frozen = CropTrainSettings(epochs=1, learning_rate=1e-12, threads=1)  # the network stays as it started
    with pytest.raises(ValueError, match="finds none of the .* pole crops of the valid frames"):
        train_robot_front_end([synth_dataset], tmp_path / "robot", frozen, progress=False)
    assert not (tmp_path / "robot").exists()


def test_a_tiny_frame_is_refused_by_check_and_has_no_candidates(dataset_copy, capsys, tmp_path, monkeypatch):
    from naoslam.perception.two_stage import CropDetector

    monkeypatch.chdir(tmp_path)
    cv2.imwrite(str(first_image(dataset_copy)), np.zeros((1, 1, 3), np.uint8))
    assert main(["check", str(dataset_copy)]) == 1
    assert "image is 1x1 px: too small to show a pole" in " ".join(capsys.readouterr().out.split())
    assert CropDetector("shipped-robot")(np.zeros((1, 1, 3), np.uint8)) == []


def test_a_missing_robot_checkpoint_is_called_missing(synth_dataset, tmp_path, capsys):
    lines = _refusal_lines(["train-robot", str(synth_dataset), "--out", str(tmp_path / "robot"), "--weights",
                            str(tmp_path / "none.pt")], capsys)
    assert "none.pt: no such checkpoint" in lines[0] and "FileNotFoundError" not in lines[0], lines


def test_a_robot_teacher_that_is_missing_not_a_crop_network_or_of_another_crop_size_is_refused_in_one_line(
        synth_dataset, tmp_path, capsys):
    import torch

    from detector.crops.network import CropArchitecture, PoleCropNet
    from detector.crops.train import save_checkpoint
    from detector.crops.settings import CropTrainSettings

    out = tmp_path / "robot"
    other_size = save_checkpoint(PoleCropNet(CropArchitecture((16, 32), (8, 8), (2, 2), 8)), tmp_path / "small.pt",
                                 [], CropTrainSettings())
    torch.save({"kind": "something else"}, tmp_path / "other.pt")
    for teacher, message in ((tmp_path / "none.pt", "none.pt: no such checkpoint"),
                             (tmp_path / "other.pt", "other.pt: not a crop network checkpoint"),
                             (other_size, "small.pt: its crop network looks at 16x32 crops, the one trained here at "
                                          "24x48")):
        lines = _refusal_lines(["train-robot", str(synth_dataset), "--out", str(out), "--teacher", str(teacher)],
                               capsys)
        assert message in lines[0] and "Error" not in lines[0], lines
    assert not out.exists()


def test_train_robot_with_no_epochs_asks_for_the_network_to_start_from(synth_dataset, tmp_path, capsys):
    """`--epochs 0` trains only on the second looks of a network or its preclassifier: without --weights there is
    none, and with no second-look or preclassifier epochs either there is nothing to train."""
    out = tmp_path / "robot"
    lines = _refusal_lines(["train-robot", str(synth_dataset), "--out", str(out), "--epochs", "0",
                            "--second-look-epochs", "6"], capsys)
    assert "--epochs 0 trains no new crop network" in lines[0] and "--weights" in lines[0], lines
    lines = _refusal_lines(["train-robot", str(synth_dataset), "--out", str(out), "--epochs", "0", "--weights",
                            str(ROBOT_WEIGHTS), "--preclassifier-epochs", "0"], capsys)
    assert "0 epochs, 0 second-look epochs and 0 preclassifier epochs train nothing" in lines[0], lines
    assert not out.exists()


def test_evaluate_says_when_pose_finds_no_recorded_pose(dataset_copy, tmp_path, capsys):
    (dataset_copy / "annotations.json").unlink()
    assert main(["evaluate", str(dataset_copy), "--model", "colour-filter", "--pose", "--out",
                 str(tmp_path / "ev")]) == 0
    assert "note: --pose: none of the test frames record their camera pose" in capsys.readouterr().out


def test_evaluate_names_recorded_poses_no_front_end_can_measure_on(dataset_copy, tmp_path, capsys):
    """A camera under the floor and a pitch that is not a number: every test frame records a pose, two of them
    impossible; the note says so with the first frame and why, not that they record none."""
    annotations = dataset_copy / "annotations.json"
    data = json.loads(annotations.read_text())
    tests = sorted(path.name for path in (dataset_copy / "test" / "images").iterdir())[:2]
    data["images"][tests[0]]["camera"]["height_m"] = -0.5
    data["images"][tests[1]]["camera"]["pitch_rad"] = float("nan")
    annotations.write_text(json.dumps(data))
    assert main(["evaluate", str(dataset_copy), "--model", "colour-filter", "--pose", "--out",
                 str(tmp_path / "ev")]) == 0
    out = capsys.readouterr().out
    assert "record their camera pose" not in out
    assert f"note: --pose: 2 of the test frames record a pose no front end can measure on and are searched whole " \
           f"({tests[0]}: camera height -0.5 m" in out


def test_finetune_on_an_export_without_poles_names_the_export_and_a_fix_it_has(dataset_copy, tmp_path, capsys):
    for label in dataset_copy.glob("*/labels/*.txt"):
        label.write_text("")
    lines = _refusal_lines(["finetune", str(dataset_copy), "--out", str(tmp_path / "run"), "--model", "robot"], capsys)
    assert f"{dataset_copy}: no annotated pole" in lines[0] and "annotate the poles" in lines[0], lines
    assert "--paint-from" not in "\n".join(lines) and str(tmp_path / "run") not in lines[0].split(" - ")[0], lines


@pytest.mark.parametrize("damage", [
    '{"format": 1, "kind": "stages", "written_by": "poles", "render": "done"}',
    '{"format": 1, "kind": "stages", "written_by": "poles", "render": {"name": "render", "key": "k", '
    '"status": "done", "seconds": 1.0, "note": "added by hand"}}',
    '{"format": 1, "kind": "stages", "written_by": "poles", "render": {"na',
    '{"format": "1", "kind": "stages", "written_by": "poles"}'])
def test_a_damaged_stage_ledger_says_what_to_do_with_the_run_folder(damage, tmp_path):
    """A string for an entry, a field added by hand, a truncated file, a format number written as text: one message
    that names the file and says the folder cannot be resumed, never a TypeError."""
    from detector.stages import StageLedger

    (tmp_path / "stages.json").write_text(damage)
    with pytest.raises(ValueError) as refused:
        StageLedger(tmp_path)
    message = str(refused.value)
    assert message.startswith(str(tmp_path / "stages.json")) and "TypeError" not in message
    assert f"the run folder {tmp_path} cannot be resumed - remove it to start the run again" in message


def test_a_maybe_threshold_above_the_threshold_is_refused_naming_the_options(tmp_path, capsys):
    lines = _refusal_lines(["slam", "--sim", "square", "--frontend", "shipped-robot", "--conf", "0.5",
                            "--maybe-conf", "0.9", "--out", str(tmp_path / "out")], capsys)
    assert lines[0].startswith("poles slam: --maybe-conf 0.9 lies above --conf 0.5") and "maybe_confidence" not in lines[0]
    assert not (tmp_path / "out").exists()


def test_fix_counts_a_coco_class_once_whatever_the_splits_that_label_it(dataset_copy, tmp_path, capsys):
    """A COCO export has one annotations file per split, and each refuses a class that names no landmark: --fix
    once said "30 class(es)" for an export of 10."""
    coco = to_coco(dataset_copy, tmp_path / "coco")
    splits = 0
    for path in sorted(coco.glob("*/_annotations.coco.json")):
        data = json.loads(path.read_text())
        data["categories"][1]["name"] = "midrib"
        splits += any(a["category_id"] == 1 for a in data["annotations"])
        path.write_text(json.dumps(data))
    assert splits >= 2
    before = tree_hash(coco)
    assert main(["check", str(coco), "--fix", "--out", str(tmp_path / "fixed")]) != 0
    refusal = " ".join(capsys.readouterr().err.split())
    assert refusal.count("category 1 'midrib' names no landmark and labels") == splits
    assert "--fix does not delete the outlines of 1 class(es)" in refusal, refusal
    assert not (tmp_path / "fixed").exists() and tree_hash(coco) == before


def test_evaluate_says_a_dataset_s_warning_once_whatever_the_models(tmp_path, capsys):
    """The square-frame warning was printed once by the command's own check and again by each model's evaluation."""
    data = generate_dataset(tmp_path / "square", SynthJob(6, seed=3, width=96, height=96), workers=1, progress=False)
    assert main(["evaluate", str(data), "--model", "shipped-robot", "--model", "colour-filter",
                 "--out", str(tmp_path / "eval")]) == 0
    assert capsys.readouterr().err.count("every image is square (96x96)") == 1
