"""Real exports through every command: class identity by name, COCO everywhere, box-only exports refused, valid
oddities accepted, a check report a person can read."""
from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from detector.cli import main
from detector.datasets import DatasetError, load_dataset
from detector.datasets.labels import BOX_ONLY
from tests.test_bad_input import coco_edit, first_label, to_coco, tree_hash

ALPHABETICAL = ["bp", "gp", "pb", "pg", "py", "yp"]  # how Roboflow orders the six classes


def poles_by_name(data: Path) -> Counter:
    """(image stem, class, outline centre rounded to 1/100) for every pole: equal means same poles, same classes."""
    return Counter((s.image.stem, i.cls, *np.round(i.polygon.mean(axis=0), 2)) for s in load_dataset(data).samples
                   if s.image is not None for i in s.instances)


def reorder_classes(data: Path, names: list[str]) -> None:
    """Rewrite data.yaml with ``names`` and every label's class ids to match: the same poles, another order."""
    old = yaml.safe_load((data / "data.yaml").read_text())["names"]
    for label in data.rglob("labels/*.txt"):
        lines = [line.split() for line in label.read_text().splitlines() if line.strip()]
        label.write_text("".join(" ".join([str(names.index(old[int(t[0])]))] + t[1:]) + "\n" for t in lines))
    config = yaml.safe_load((data / "data.yaml").read_text())
    config["names"] = names
    (data / "data.yaml").write_text(yaml.safe_dump(config))


@pytest.fixture
def alphabetical(dataset_copy) -> Path:
    reorder_classes(dataset_copy, ALPHABETICAL)
    return dataset_copy


def test_alphabetical_export_keeps_every_class_through_every_command(alphabetical, tmp_path, capsys):
    truth = poles_by_name(alphabetical)
    assert {c for _, c, *_ in truth} >= {"pb", "yp"}
    assert main(["check", str(alphabetical)]) == 0
    assert main(["convert", str(alphabetical), "--out", str(tmp_path / "converted")]) == 0
    assert main(["split", "--data", str(alphabetical), "--out", str(tmp_path / "split")]) == 0
    assert main(["augment", "--data", str(alphabetical), "--out", str(tmp_path / "augmented"), "--copies", "1"]) == 0
    for out in ("converted", "split"):
        assert poles_by_name(tmp_path / out) == truth, out
    augmented = poles_by_name(tmp_path / "augmented")
    assert all(augmented[key] >= count for key, count in truth.items())  # originals kept, copies added


def test_names_keyed_by_id_are_read_in_id_order_past_ten_classes(dataset_copy):
    """``names: {0: ..., 11: ...}`` was sorted as text (0, 1, 10, 11, 2, ...): from class 2 on every class took
    another's name. Here six other classes come first and the poles are ids 6-11."""
    truth = poles_by_name(dataset_copy)
    poles = yaml.safe_load((dataset_copy / "data.yaml").read_text())["names"]
    reorder_classes(dataset_copy, [f"other{i}" for i in range(6)] + poles)
    config = yaml.safe_load((dataset_copy / "data.yaml").read_text())
    config["names"] = dict(enumerate(config["names"]))
    (dataset_copy / "data.yaml").write_text(yaml.safe_dump(config))
    assert poles_by_name(dataset_copy) == truth
    config["names"] = {0: "bp", 2: "gp"}
    (dataset_copy / "data.yaml").write_text(yaml.safe_dump(config))
    with pytest.raises(DatasetError, match="are not the class ids 0-1"):
        load_dataset(dataset_copy)


def test_a_stale_path_in_data_yaml_is_refused_in_one_line_that_names_the_fix(dataset_copy, tmp_path, capsys):
    """A data.yaml written for Ultralytics on another machine (``path: /home/someone/poles``) was reported as "no
    images found in any split" and one warning per split."""
    config = yaml.safe_load((dataset_copy / "data.yaml").read_text())
    config["path"] = str(tmp_path / "on-another-machine")
    (dataset_copy / "data.yaml").write_text(yaml.safe_dump(config))
    assert main(["check", str(dataset_copy)]) == 1
    report = capsys.readouterr().out
    assert "names no folder" in report and "delete the `path:` line" in report and "no images found" not in report


@pytest.mark.parametrize("layout", ["yolov8", "coco"])
def test_a_class_that_names_no_landmark_is_refused_only_where_outlines_use_it(dataset_copy, tmp_path, layout, capsys):
    """Roboflow lists every class of a project. An unused 'robot' class was refused, and the advice, `--rename
    'robot=bp'`, met the next refusal: two classes meaning bp."""
    truth = poles_by_name(dataset_copy)
    if layout == "coco":
        data = to_coco(dataset_copy, tmp_path / "coco")
        coco_edit(data, lambda d: d["categories"].append({"id": 7, "name": "robot", "supercategory": "poles"}))
    else:
        data = dataset_copy
        config = yaml.safe_load((data / "data.yaml").read_text())
        config["names"] = [*config["names"], "robot"]
        (data / "data.yaml").write_text(yaml.safe_dump(config))
    assert main(["convert", str(data), "--out", str(tmp_path / "out")]) == 0
    assert poles_by_name(tmp_path / "out") == truth
    assert any(p.severity == "note" and "'robot' names no landmark and labels no outline: ignored" in p.message
               for p in load_dataset(data).problems)
    if layout == "coco":
        coco_edit(data, lambda d: d["annotations"][0].__setitem__("category_id", 7))
    else:
        label = next(p for p in sorted(data.rglob("labels/*.txt")) if p.read_text().strip())
        label.write_text(label.read_text().replace(label.read_text().split()[0], "6.0", 1))  # the parser reads 6.0
    capsys.readouterr()
    assert main(["convert", str(data), "--out", str(tmp_path / "refused")]) == 2
    assert "'robot' names no landmark and labels 1 outline(s)" in capsys.readouterr().err
    # --fix would drop that outline and write a copy that passes check: it refuses instead, naming --rename
    assert main(["check", str(data), "--fix", "--out", str(tmp_path / "fixed")]) != 0
    refusal = capsys.readouterr().err
    assert "--fix does not delete the outlines of 1 class(es)" in refusal and "--rename" in refusal
    assert not (tmp_path / "fixed").exists()


def test_alphabetical_export_trains_exports_and_evaluates(alphabetical, tmp_path):
    before = tree_hash(alphabetical)
    run = tmp_path / "run"
    assert main(["train", "--data", str(alphabetical), "--out", str(run), "--weights", "scratch", "--epochs", "1",
                 "--imgsz", "64", "--batch", "8"]) == 0
    view = load_dataset(run / "dataset")
    assert poles_by_name(run / "dataset") == poles_by_name(alphabetical)
    assert yaml.safe_load((run / "dataset" / "data.yaml").read_text())["names"] == ["bp", "gp", "yp", "pb", "pg", "py"]
    assert len(view.samples) == len(load_dataset(alphabetical).samples)
    assert main(["export", "--weights", str(run / "weights" / "best.pt"), "--out", str(tmp_path / "m.onnx"),
                 "--imgsz", "96", "128", "--data", str(alphabetical), "--conf", "0.9"]) == 0
    assert main(["evaluate", "--data", str(alphabetical), "--out", str(tmp_path / "eval")]) == 0
    assert tree_hash(alphabetical) == before


def test_single_class_export_keeps_its_class(dataset_copy, tmp_path):
    reorder_classes(dataset_copy, ["bp", "gp", "yp", "pb", "pg", "py"])
    for label in dataset_copy.rglob("labels/*.txt"):  # keep only pb poles, as class 0 of names ['pb']
        lines = [line.split() for line in label.read_text().splitlines() if line.strip()]
        label.write_text("".join(" ".join(["0"] + t[1:]) + "\n" for t in lines if t[0] == "3"))
    config = yaml.safe_load((dataset_copy / "data.yaml").read_text())
    (dataset_copy / "data.yaml").write_text(yaml.safe_dump({**config, "names": ["pb"], "nc": 1}))
    truth = poles_by_name(dataset_copy)
    assert truth and {c for _, c, *_ in truth} == {"pb"}
    assert main(["split", "--data", str(dataset_copy), "--out", str(tmp_path / "split")]) == 0
    assert poles_by_name(tmp_path / "split") == truth


def test_coco_export_keeps_its_poles_through_split_augment_and_train(synth_dataset, tmp_path):
    coco = to_coco(synth_dataset, tmp_path / "coco")
    truth = poles_by_name(coco)
    assert sum(truth.values()) > 0
    assert main(["split", "--data", str(coco), "--out", str(tmp_path / "split")]) == 0
    assert main(["augment", "--data", str(coco), "--out", str(tmp_path / "aug"), "--copies", "1"]) == 0
    assert poles_by_name(tmp_path / "split") == truth
    assert all(poles_by_name(tmp_path / "aug")[key] >= n for key, n in truth.items())
    before = tree_hash(coco)
    assert main(["train", "--data", str(coco), "--out", str(tmp_path / "run"), "--weights", "scratch", "--epochs", "1",
                 "--imgsz", "64", "--batch", "8"]) == 0
    assert tree_hash(coco) == before


def box_only(data: Path) -> Path:
    """Turn every polygon into a YOLO box line (class cx cy w h), as a detection export writes them."""
    for label in data.rglob("labels/*.txt"):
        lines = []
        for line in label.read_text().splitlines():
            values = np.array(line.split()[1:], float).reshape(-1, 2)
            (x0, y0), (x1, y1) = values.min(0), values.max(0)
            lines.append(f"{line.split()[0]} {(x0 + x1) / 2:.6f} {(y0 + y1) / 2:.6f} {x1 - x0:.6f} {y1 - y0:.6f}\n")
        label.write_text("".join(lines))
    return data


@pytest.mark.parametrize("command", ["check-fix", "convert", "split", "augment", "train", "evaluate"])
def test_box_only_export_is_refused_in_the_same_words_and_never_fixed(command, dataset_copy, tmp_path, capsys):
    data = box_only(dataset_copy)
    out = tmp_path / "out"
    argv = {"check-fix": ["check", str(data), "--fix", "--out", str(out)],
            "convert": ["convert", str(data), "--out", str(out)],
            "split": ["split", "--data", str(data), "--out", str(out)],
            "augment": ["augment", "--data", str(data), "--out", str(out)],
            "train": ["train", "--data", str(data), "--out", str(out), "--epochs", "1", "--imgsz", "64"],
            "evaluate": ["evaluate", "--data", str(data), "--out", str(out)]}[command]
    assert main(argv) == 2
    captured = capsys.readouterr()
    assert BOX_ONLY in captured.err + captured.out
    assert not out.exists()


def yolo_frames_of_boxes_and_other_classes(data: Path, tmp_path: Path) -> Path:
    """Every train frame labelled empty but two: one with a box, one with an outline of a class that is no pole."""
    labels = sorted((data / "train" / "labels").glob("*.txt"))
    for label in labels:
        label.write_text("")
    config = yaml.safe_load((data / "data.yaml").read_text())
    config["names"] = list(config["names"]) + ["referee"]
    (data / "data.yaml").write_text(yaml.safe_dump(config))
    labels[0].write_text("0 0.5 0.5 0.1 0.3\n")
    labels[1].write_text(f"{len(config['names']) - 1} 0.1 0.1 0.2 0.1 0.2 0.3\n")
    return data


def coco_frames_of_boxes_and_other_classes(data: Path, tmp_path: Path) -> Path:
    """The same in a COCO export: a box without a polygon, and an outline of a category that is no pole."""
    coco = to_coco(data, tmp_path / "coco")

    def change(json_data: dict) -> None:
        first, second = json_data["images"][0]["id"], json_data["images"][1]["id"]
        json_data["categories"].append({"id": 99, "name": "referee", "supercategory": "none"})
        json_data["annotations"] = [
            {"id": 0, "image_id": first, "category_id": 1, "bbox": [10, 10, 20, 60], "segmentation": []},
            {"id": 1, "image_id": second, "category_id": 99, "segmentation": [[10, 10, 30, 10, 30, 60]]}]

    coco_edit(coco, change)
    return coco


@pytest.mark.parametrize("make", [yolo_frames_of_boxes_and_other_classes, coco_frames_of_boxes_and_other_classes])
def test_check_counts_box_only_frames_and_frames_of_other_classes_apart_from_empty_ones(make, dataset_copy, tmp_path,
                                                                                      capsys, monkeypatch):
    """A frame whose labels are boxes, or outlines of classes that name no pole, is not a frame showing no pole."""
    from detector.datasets.check import check_dataset

    monkeypatch.delenv("COLUMNS", raising=False)  # as logged: the table is printed whole

    data = make(dataset_copy, tmp_path)
    samples = check_dataset(data, progress=False).dataset.split("train")
    assert [s.boxes for s in samples].count(1) == 1 and sum(s.unread for s in samples) == 2
    assert sum(s.negative for s in samples) == len(samples) - 2
    assert main(["check", str(data)]) == 1
    lines = capsys.readouterr().out.splitlines()
    header = next(line for line in lines if "split" in line)
    assert "no pole read" in header
    cells = next(line for line in lines if line.strip("│┃ ").startswith("train")).replace("│", " ").split()
    assert cells[1:5] == [str(len(samples)), str(len(samples) - 2), "1", "1"]  # images, empty, box-only, no pole read


def test_check_summarises_many_problems_and_writes_the_whole_list(dataset_copy, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for label in sorted(dataset_copy.rglob("labels/*.txt")):
        label.write_text(label.read_text() + "9 0.1 0.1 0.2 0.1 0.2 0.2\n0 0.1 0.1 0.2\n")
    assert main(["check", str(dataset_copy)]) == 1
    printed = capsys.readouterr().out
    listing = tmp_path / f"check-{dataset_copy.name}.txt"
    assert listing.is_file() and len(listing.read_text().splitlines()) >= 48
    assert "24 x error: class id 9 out of range" in " ".join(printed.split())
    assert len(printed.splitlines()) < 40


def test_check_names_each_example_whose_particulars_differ_from_the_headline(dataset_copy, capsys):
    labels = sorted(dataset_copy.rglob("labels/*.txt"))
    labels[0].write_text("7 0.1 0.1 0.2 0.1 0.2 0.5\n")
    labels[1].write_text("9 0.1 0.1 0.2 0.1 0.2 0.5\n")
    assert main(["check", str(dataset_copy)]) == 1
    printed = " ".join(capsys.readouterr().out.split())
    assert "2 x error: class id" in printed
    assert "class id 7 out of range" in printed and "class id 9 out of range" in printed


@pytest.mark.parametrize("run_from", ["inside the dataset", "a refused --fix copy"])
def test_check_never_writes_its_list_into_the_dataset(run_from, dataset_copy, tmp_path, monkeypatch):
    for label in sorted(dataset_copy.rglob("labels/*.txt")):
        label.write_text(label.read_text() + "9 0.1 0.1 0.2 0.1 0.2 0.2\n0 0.1 0.1 0.2\n")
    files = sorted(dataset_copy.rglob("*"))
    if run_from == "inside the dataset":
        monkeypatch.chdir(dataset_copy)
        assert main(["check", "."]) == 1
        assert (dataset_copy.parent / f"check-{dataset_copy.name}.txt").is_file()  # beside the dataset
    else:
        assert main(["check", str(dataset_copy), "--fix", "--out", str(dataset_copy / "clean")]) == 2
    assert sorted(dataset_copy.rglob("*")) == files


def test_rename_maps_an_exports_own_class_names(dataset_copy, tmp_path, capsys):
    truth = poles_by_name(dataset_copy)
    config = yaml.safe_load((dataset_copy / "data.yaml").read_text())
    names = ["blue-pink", "green-pink", "yellow-pink", "pink-blue", "pink-green", "ball-pole"]
    (dataset_copy / "data.yaml").write_text(yaml.safe_dump({**config, "names": names}))
    assert main(["convert", str(dataset_copy), "--out", str(tmp_path / "refused")]) == 2
    assert "'ball-pole' names no landmark" in capsys.readouterr().err
    assert main(["convert", str(dataset_copy), "--out", str(tmp_path / "out"), "--rename", "ball-pole=py"]) == 0
    assert poles_by_name(tmp_path / "out") == truth and sum(truth.values()) > 0


def test_valid_oddities_are_accepted_unchanged(dataset_copy, tmp_path):
    label = first_label(dataset_copy)
    label.write_bytes(b"\xef\xbb\xbf" + label.read_bytes().replace(b"\n", b"\r\n"))  # UTF-8 BOM and CRLF
    images = sorted((dataset_copy / "test" / "images").glob("*.jpg"))
    frame = cv2.imread(str(images[0]))
    cv2.imwrite(str(images[0].with_suffix(".png")), frame)  # a PNG named .jpg
    images[0].unlink()
    images[0].with_suffix(".png").rename(images[0])
    cv2.imwrite(str(images[1]), cv2.cvtColor(cv2.imread(str(images[1])), cv2.COLOR_BGR2GRAY))  # grey
    sixteen = images[2].with_suffix(".png")
    cv2.imwrite(str(sixteen), cv2.imread(str(images[2])).astype(np.uint16) * 257)  # 16-bit
    images[2].unlink()
    (images[2].parent.parent / "labels" / f"{images[2].stem}.txt").rename(
        images[2].parent.parent / "labels" / f"{sixteen.stem}.txt")
    config = yaml.safe_load((dataset_copy / "data.yaml").read_text())
    spelt = ["Blue over Pink", "green-pink", "yellow / pink", "pink-blue", "Pink Green", "pink-yellow"]
    (dataset_copy / "data.yaml").write_text(yaml.safe_dump({**config, "names": spelt}))
    truth = poles_by_name(dataset_copy)
    assert main(["check", str(dataset_copy)]) == 0
    assert main(["convert", str(dataset_copy), "--out", str(tmp_path / "out")]) == 0
    assert poles_by_name(tmp_path / "out") == truth


def test_coco_without_sizes_and_with_flat_polygons_and_a_foreign_annotations_file(synth_dataset, tmp_path, capsys):
    coco = to_coco(synth_dataset, tmp_path / "coco")
    path = coco / "train" / "_annotations.coco.json"
    data = json.loads(path.read_text())
    for image in data["images"]:
        image.pop("width"), image.pop("height")
    for annotation in data["annotations"]:
        annotation["segmentation"] = annotation["segmentation"][0]
    path.write_text(json.dumps(data))
    assert main(["convert", str(coco), "--out", str(tmp_path / "yolo")]) == 0
    assert poles_by_name(tmp_path / "yolo") == poles_by_name(synth_dataset)
    (tmp_path / "yolo" / "annotations.json").write_text(json.dumps([{"file": "x.jpg"}]))
    assert main(["evaluate", "--data", str(tmp_path / "yolo"), "--out", str(tmp_path / "eval")]) == 0
    assert "not an annotations.json of `poles synth`" in capsys.readouterr().out


@pytest.mark.parametrize("command", ["check", "split"])
def test_a_folder_that_cannot_be_read_is_named_with_the_fix(command, dataset_copy, tmp_path, capsys, monkeypatch):
    """As a user meets a folder copied from another account (root reads everything, so the refusal is imitated)."""
    locked = (dataset_copy / "valid" / "images").resolve()
    iterdir = Path.iterdir

    def refuse(folder: Path):
        if folder.resolve() == locked:
            raise PermissionError(13, "Permission denied", str(folder))
        return iterdir(folder)

    monkeypatch.setattr(Path, "iterdir", refuse)
    argv = ["check", str(dataset_copy)] if command == "check" else \
        ["split", "--data", str(dataset_copy), "--out", str(tmp_path / "out")]
    assert main(argv) in (1, 2)
    captured = capsys.readouterr()
    printed = " ".join((captured.out + captured.err).split())
    assert "folder cannot be read (Permission denied)" in printed and f"chmod -R u+rX {locked}" in printed
    assert "Traceback" not in printed and not (tmp_path / "out").exists()
