"""Reading, checking, fixing and converting datasets: every bad input names its file, line and fix."""
from __future__ import annotations

import hashlib
import io
import json
import shutil
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from detector.cli import main
from detector.datasets import DatasetError, load_dataset, write_dataset
from detector.datasets.check import check_dataset, write_fixed_copy
from detector.datasets.intake import open_dataset
from detector.datasets.jpeg import truncated_jpeg
from detector.datasets.names import canonical_class
from naoslam.landmarks import CLASSES


def _first_labelled(root: Path, split: str = "train") -> Path:
    return next(p for p in sorted((root / split / "labels").glob("*.txt")) if p.read_text().strip())


def _problems(root: Path, severity: str = "error"):
    return [p for p in check_dataset(root, progress=False).problems if p.severity == severity]


@pytest.mark.parametrize("name, code", [
    ("BP", "bp"), ("b-p", "bp"), ("Blue over Pink", "bp"), ("sky blue / pink", "bp"), ("pink/green", "pg"),
    ("pole_bp", "bp"), ("PY pole", "py"), ("landmark-gp", "gp"), ("BluePink", "bp"), ("YELLOWPINK", "yp"),
    ("PinkSkyBlue", "pb"),
    ("green", None), ("ball-pole", None), ("bp or pb", None), ("blue pole bp", None), ("pink-pink", None),
])
def test_class_names_map_to_codes_or_to_none(name, code):
    assert canonical_class(name) == code


def test_synthetic_dataset_is_clean_and_canonical(synth_dataset):
    report = check_dataset(synth_dataset, progress=False)
    assert report.errors == []
    assert "names: ['bp', 'gp', 'yp', 'pb', 'pg', 'py']" in (synth_dataset / "data.yaml").read_text()
    dataset = load_dataset(synth_dataset)
    assert {s.split for s in dataset.samples} == {"train", "valid", "test"}
    assert len(dataset.split("train")) == round(0.7 * 24) and len(dataset.split("test")) == round(0.2 * 24)
    annotations = json.loads((synth_dataset / "annotations.json").read_text())
    for sample in dataset.samples:
        truth = annotations["images"][sample.image.name]["landmarks"]
        assert [t["cls"] for t in truth] == [i.cls for i in sample.instances]


def _append_line(path: Path, line: str) -> int:
    lines = path.read_text().splitlines() + [line]
    path.write_text("\n".join(lines) + "\n")
    return len(lines)


@pytest.mark.parametrize("line, message", [
    ("9 0.1 0.1 0.2 0.1 0.2 0.2", "class id 9 out of range"),
    ("0 0.1 0.1 0.2 0.1 0.2", "odd number of coordinates"),
    ("0 0.1 0.1 0.2 0.2", "segmentation labels needed"),
    ("0 0.1 0.1 0.2 0.1 0.3 0.4 0.5 0.6 0.7 0.8 0.9 0.9 0.1 0.1 0.2 0.2 0.3", "odd number"),
    ("0 0.1 0.1 0.2 0.2 0.1 0.1 0.2 0.2", "zero area"),
    ("0 10 20 30 20 30 40", "outside [0, 1]"),
    ("0 0.1 0.1", "only 1 point(s)"),
    ("0 0.1 abc 0.2 0.1 0.2 0.2", "not a number"),
])
def test_bad_label_line_is_reported_with_file_and_line(dataset_copy, line, message):
    label = _first_labelled(dataset_copy)
    number = _append_line(label, line)
    errors = _problems(dataset_copy)
    assert any(p.path == label and p.line == number and message in p.message for p in errors), errors


def test_slightly_outside_coordinates_are_a_warning_and_clipped(dataset_copy):
    label = _first_labelled(dataset_copy)
    number = _append_line(label, "0 -0.005 0.1 0.2 0.1 0.2 0.3")
    warnings = _problems(dataset_copy, "warning")
    assert any(p.path == label and p.line == number for p in warnings)
    sample = next(s for s in load_dataset(dataset_copy).samples if s.label == label)
    assert sample.instances[-1].polygon.min() == 0.0


def test_label_without_image_and_image_without_label(dataset_copy):
    label = _first_labelled(dataset_copy)
    image = dataset_copy / "train" / "images" / f"{label.stem}.jpg"
    image.unlink()
    other = _first_labelled(dataset_copy, "test")
    other.unlink()
    errors = _problems(dataset_copy)
    assert any(p.path == label and "label without an image" in p.message for p in errors)
    notes = _problems(dataset_copy, "note")
    assert any(p.path.stem == other.stem and "read as a negative" in p.message for p in notes)


def test_corrupt_and_truncated_images(dataset_copy):
    images = sorted((dataset_copy / "train" / "images").glob("*.jpg"))
    images[0].write_bytes(b"not an image at all")
    data = images[1].read_bytes()
    images[1].write_bytes(data[: len(data) * 2 // 3])
    report = check_dataset(dataset_copy, progress=False)
    assert any(p.path == images[0] and "cannot be decoded" in p.message for p in report.errors)
    assert any(p.path == images[1] and "truncated" in p.message for p in report.errors)


def test_bytes_after_the_end_marker_are_no_problem_and_fix_copies_the_image_as_it_is(dataset_copy, tmp_path):
    """A camera that saves its fixed-size capture buffer pads the JPEG after its end marker: the image is whole."""
    image = sorted((dataset_copy / "train" / "images").glob("*.jpg"))[0]
    padded = image.read_bytes() + bytes(256)
    image.write_bytes(padded)
    report = check_dataset(dataset_copy, progress=False)
    assert [p.message for p in report.problems if p.path == image] == []
    write_fixed_copy(report, tmp_path / "clean")
    assert (tmp_path / "clean" / "train" / "images" / image.name).read_bytes() == padded


def _with_exif_thumbnail(jpeg: bytes, thumbnail: bytes) -> bytes:
    """``jpeg`` with an APP1 segment after its start marker that holds ``thumbnail``, as cameras write EXIF."""
    payload = b"Exif\x00\x00" + thumbnail
    return jpeg[:2] + b"\xff\xe1" + (len(payload) + 2).to_bytes(2, "big") + payload + jpeg[2:]


@settings(max_examples=60, deadline=None)
@given(cut=st.floats(0.0, 1.0, exclude_max=True), progressive=st.booleans(), thumbnail=st.booleans(),
       padding=st.binary(max_size=64))
def test_a_jpeg_is_truncated_exactly_when_its_data_stop_before_the_end_marker(cut, padding, progressive, thumbnail):
    """Padding may hold any bytes, a start-of-scan marker included; a thumbnail's own end marker does not end the
    image, so a file cut after it is still truncated."""
    frame = cv2.GaussianBlur(np.random.default_rng(3).integers(0, 256, (96, 128, 3), np.uint8), (7, 7), 2)
    data = cv2.imencode(".jpg", frame, [cv2.IMWRITE_JPEG_PROGRESSIVE, int(progressive)])[1].tobytes()
    if thumbnail:
        data = _with_exif_thumbnail(data, cv2.imencode(".jpg", frame[::8, ::8])[1].tobytes())
    assert not truncated_jpeg(data + padding)
    assert not truncated_jpeg(data + b"\xff\xda" + padding)
    assert truncated_jpeg(data[:3 + int(cut * (len(data) - 4))])


@settings(max_examples=200, deadline=None)
@given(rest=st.binary(max_size=200))
def test_any_bytes_after_a_jpeg_start_are_read_to_an_answer(rest):
    """Corrupt segment lengths and markers in any order end the walk, and without an end marker nothing is whole."""
    data = b"\xff\xd8\xff" + rest
    assert truncated_jpeg(data) or b"\xff\xd9" in data


def test_duplicate_stems_within_and_across_splits(dataset_copy):
    train_image = sorted((dataset_copy / "train" / "images").glob("*.jpg"))[0]
    shutil.copy(train_image, dataset_copy / "test" / "images" / train_image.name)
    shutil.copy(train_image, train_image.with_suffix(".png"))
    messages = [p.message for p in _problems(dataset_copy)]
    assert any("leak between splits" in m for m in messages)
    assert any("same file stem" in m for m in messages)


def test_unknown_class_name_in_yaml(dataset_copy):
    yaml_path = dataset_copy / "data.yaml"
    yaml_path.write_text(yaml_path.read_text().replace("'bp'", "'ball'"))
    errors = _problems(dataset_copy)
    assert any(p.path == yaml_path and "'ball' names no landmark" in p.message for p in errors)


def test_classes_are_mapped_by_name_not_index(synth_dataset, tmp_path):
    """A dataset that lists the classes in another order (and spells them out) reads to the same instances."""
    order = ["pink-yellow", "Blue over Pink", "g-p", "PB", "pink green", "yellow/pink"]
    permuted = Path(shutil.copytree(synth_dataset, tmp_path / "permuted"))
    new_index = {canonical_class(name): i for i, name in enumerate(order)}
    for label in permuted.glob("*/labels/*.txt"):
        lines = [l.split(" ", 1) for l in label.read_text().splitlines()]
        label.write_text("".join(f"{new_index[CLASSES[int(c)]]} {rest}\n" for c, rest in lines))
    (permuted / "data.yaml").write_text(f"train: ../train/images\nval: ../valid/images\ntest: ../test/images\nnc: 6\nnames: {order}\n")
    original, reread = load_dataset(synth_dataset), load_dataset(permuted)
    assert [[i.cls for i in s.instances] for s in original.samples] == [[i.cls for i in s.instances] for s in reread.samples]


def _tree_hash(root: Path) -> str:
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*")):
        if path.is_file():
            digest.update(str(path.relative_to(root)).encode() + path.read_bytes())
    return digest.hexdigest()


def test_fix_writes_a_clean_copy_and_leaves_the_input(dataset_copy, tmp_path):
    label = _first_labelled(dataset_copy)
    _append_line(label, "9 0.1 0.1 0.2 0.1 0.2 0.2")
    sorted((dataset_copy / "valid" / "images").glob("*.jpg"))[0].write_bytes(b"broken")
    before = _tree_hash(dataset_copy)
    assert main(["check", str(dataset_copy), "--fix", "--out", str(tmp_path / "clean")]) == 1
    assert _tree_hash(dataset_copy) == before
    assert check_dataset(tmp_path / "clean", progress=False).errors == []
    with pytest.raises(ValueError, match="overlaps the input"):
        write_fixed_copy(check_dataset(dataset_copy, progress=False), dataset_copy / "inside")


def test_cli_refuses_fix_without_out(dataset_copy, capsys):
    assert main(["check", str(dataset_copy), "--fix"]) == 2
    assert "never written in place" in capsys.readouterr().err


def test_check_and_convert_take_the_dataset_as_data_or_as_the_option_every_command_uses(dataset_copy, tmp_path,
                                                                                        capsys):
    assert main(["check", str(dataset_copy)]) == 0
    positional = capsys.readouterr().out
    assert main(["check", "--data", str(dataset_copy)]) == 0
    assert capsys.readouterr().out == positional
    assert main(["check"]) == 2
    assert "give the dataset once" in capsys.readouterr().err
    assert main(["check", str(dataset_copy), "--data", str(dataset_copy / "train")]) == 2
    assert "give the dataset once" in capsys.readouterr().err
    assert main(["convert", "--data", str(dataset_copy), "--out", str(tmp_path / "converted")]) == 0
    assert (tmp_path / "converted" / "data.yaml").is_file()


@pytest.mark.parametrize("command", ["check", "convert", "augment", "split", "train", "calibrate", "evaluate"])
def test_every_command_that_reads_a_dataset_takes_it_as_data_or_as_the_option(command):
    from detector.cli import build_parser
    from detector.cli.arguments import one_dataset

    out = [] if command == "check" else ["--out", "result"]
    positional = build_parser().parse_args([command, "export", *out])
    option = build_parser().parse_args([command, "--data", "export", *out])
    assert one_dataset(positional) == one_dataset(option) == Path("export")


def test_a_logged_check_keeps_its_table_headers_whole(dataset_copy, capsys, monkeypatch):
    monkeypatch.delenv("COLUMNS", raising=False)  # into a pipe, as in a CI log: rich alone would cut at 80 columns
    assert main(["check", str(dataset_copy)]) == 0
    header = next(line for line in capsys.readouterr().out.splitlines() if "split" in line)
    assert all(word in header for word in ("images", "empty", "box-only", "unreadable", "poles", "image sizes"))


def test_a_logged_progress_bar_writes_whole_lines(capsys):
    """Into a pipe tqdm would join every update into one line of the log with carriage returns."""
    from detector.console import show_progress

    assert list(show_progress(range(500), "rendering", "img")) == list(range(500))
    lines = [line.strip("\r") for line in capsys.readouterr().err.split("\n") if line.strip()]
    assert len(lines) == 2  # the start and the end, each a line of its own: nothing in between inside 30 seconds
    assert lines[0].startswith("rendering:   0%") and lines[1].startswith("rendering: 100%")
    assert "500/500" in lines[1] and "\r" not in "".join(lines)


def test_an_ultralytics_bar_in_a_log_writes_a_line_every_30_seconds_and_its_last_frame():
    """Ultralytics redraws a bar ten times a second; into a log each redraw would lengthen one line."""
    from ultralytics.utils.tqdm import TQDM

    from detector.console import LogBarStream

    now = [0.0]
    log = io.StringIO()
    stream = LogBarStream(log, clock=lambda: now[0])
    bar = TQDM(total=100, desc="epoch 1/3", file=stream, mininterval=0.0)
    for _ in range(100):
        now[0] += 1.0  # one batch a second: lines at 0, 30, 60 and 90 s, then the last frame at close
        bar.update(1)
    bar.close()
    stream.write("validating\n")
    TQDM(range(5), desc="val", file=stream, leave=False, mininterval=0.0).close()  # a cleared bar: first frame only
    lines = log.getvalue().split("\n")
    assert "\r" not in log.getvalue() and "\x1b" not in log.getvalue()
    progress = [line.split()[2] for line in lines if line.startswith("epoch 1/3:")]
    assert progress == ["0%", "30%", "60%", "90%", "100%"]
    assert lines[-3:] == ["validating", lines[-2], ""] and lines[-2].startswith("val: 0%")


@pytest.mark.parametrize("interactive", [True, False])
def test_training_bars_become_log_lines_only_where_nothing_redraws(monkeypatch, interactive):
    from detector.console import LogBarStream, bars_as_log_lines

    class Stream(io.StringIO):
        def isatty(self) -> bool:
            return interactive

    stdout = Stream()
    monkeypatch.setattr("sys.stdout", stdout)
    with bars_as_log_lines():
        assert isinstance(sys.stdout, LogBarStream) != interactive
    assert sys.stdout is stdout


def test_open_dataset_refuses_errors_naming_the_file(dataset_copy):
    label = _first_labelled(dataset_copy)
    _append_line(label, "0 0.1 0.1")
    with pytest.raises(DatasetError, match=f"{label.name}:"):
        open_dataset(dataset_copy, progress=False)


def _to_coco(root: Path, out: Path, category_order: list[str]) -> None:
    """Write a Roboflow-style COCO export of a YOLO dataset (pixel polygons, a supercategory at id 0)."""
    import cv2

    dataset = load_dataset(root)
    for split in ("train", "valid", "test"):
        folder = out / split
        folder.mkdir(parents=True)
        categories = [{"id": 0, "name": "poles", "supercategory": "none"}]
        categories += [{"id": i + 1, "name": n, "supercategory": "poles"} for i, n in enumerate(category_order)]
        coco = {"images": [], "annotations": [], "categories": categories}
        for sample in dataset.split(split):
            shutil.copy(sample.image, folder / sample.image.name)
            h, w = cv2.imread(str(sample.image)).shape[:2]
            image_id = len(coco["images"])
            coco["images"].append({"id": image_id, "file_name": sample.image.name, "width": w, "height": h})
            for instance in sample.instances:
                coco["annotations"].append({"id": len(coco["annotations"]), "image_id": image_id, "iscrowd": 0,
                                            "category_id": category_order.index(instance.cls) + 1,
                                            "segmentation": [instance.pixels(w, h).reshape(-1).tolist()]})
        (folder / "_annotations.coco.json").write_text(json.dumps(coco))


def test_coco_import_round_trips(synth_dataset, tmp_path):
    _to_coco(synth_dataset, tmp_path / "coco", list(reversed(CLASSES)))
    assert main(["convert", str(tmp_path / "coco"), "--out", str(tmp_path / "yolo")]) == 0
    original, converted = load_dataset(synth_dataset), load_dataset(tmp_path / "yolo")
    pairs = {s.image.name: s for s in original.samples}
    assert len(converted.samples) == len(original.samples)
    for sample in converted.samples:
        reference = pairs[sample.image.name]
        assert sample.split == reference.split
        assert [i.cls for i in sample.instances] == [i.cls for i in reference.instances]
        for a, b in zip(sample.instances, reference.instances):
            np.testing.assert_allclose(a.polygon, b.polygon, atol=1e-6)


def test_coco_rle_is_refused(synth_dataset, tmp_path):
    _to_coco(synth_dataset, tmp_path / "coco", list(CLASSES))
    path = tmp_path / "coco" / "train" / "_annotations.coco.json"
    coco = json.loads(path.read_text())
    coco["annotations"][0]["segmentation"] = {"counts": "abc", "size": [240, 320]}
    path.write_text(json.dumps(coco))
    assert any("RLE" in p.message for p in load_dataset(tmp_path / "coco").errors)


def test_coco_images_in_an_images_folder_are_one_kind_of_problem_that_says_where_they_are(synth_dataset, tmp_path):
    from detector.datasets.model import problem_kind

    _to_coco(synth_dataset, tmp_path / "coco", list(CLASSES))
    valid = tmp_path / "coco" / "valid"
    (valid / "images").mkdir()
    moved = [image.rename(valid / "images" / image.name) for image in sorted(valid.glob("*.jpg"))]
    errors = load_dataset(tmp_path / "coco").errors
    assert len(errors) == len(moved) > 1
    assert len({problem_kind(problem) for problem in errors}) == 1
    assert f"(it is in {valid / 'images'})" in errors[0].message


def test_two_classes_onto_one_code_merge_only_where_rename_names_both(synth_dataset, tmp_path):
    """COCO categories 1 'bp' and 2 'fence' (gp's poles): --rename fence=bp alone is refused by the categories' own
    ids, naming the --rename that did it; renaming both merges them, and a note says so."""
    _to_coco(synth_dataset, tmp_path / "coco", list(CLASSES))
    assert CLASSES[:2] == ("bp", "gp")
    for path in (tmp_path / "coco").glob("*/_annotations.coco.json"):
        coco = json.loads(path.read_text())
        coco["categories"][2]["name"] = "fence"
        path.write_text(json.dumps(coco))
    clashing = load_dataset(tmp_path / "coco", renames={"fence": "bp"}).errors
    assert any("categories 1 ('bp') and 2 ('fence') both mean bp: your --rename 'fence=bp' puts one onto the other"
               in p.message and "--rename 'bp=bp' --rename 'fence=bp'" in p.fix for p in clashing), clashing
    merged = load_dataset(tmp_path / "coco", renames={"bp": "bp", "fence": "bp"})
    assert not merged.errors
    assert any("categories 1 ('bp') and 2 ('fence') both read as bp, as --rename asks" in p.message
               for p in merged.problems)
    expected = sum(1 for s in load_dataset(synth_dataset).samples for i in s.instances if i.cls in ("bp", "gp"))
    assert sum(1 for s in merged.samples for i in s.instances if i.cls == "bp") == expected > 0


def _store_turned(image: Path) -> np.ndarray:
    """Re-save ``image`` as a phone does: pixels stored a quarter turn back, EXIF orientation 6 to turn them
    upright. Returns the upright pixels as OpenCV now reads them."""
    import cv2
    from PIL import Image

    upright = cv2.imread(str(image))
    stored = Image.fromarray(cv2.rotate(upright, cv2.ROTATE_90_COUNTERCLOCKWISE)[:, :, ::-1])
    exif = stored.getexif()
    exif[0x0112] = 6
    stored.save(image, format="PNG" if image.suffix == ".png" else "JPEG", quality=95, exif=exif.tobytes())
    return cv2.imread(str(image))


def test_coco_image_stored_turned_is_read_upright_and_a_stored_size_is_refused(synth_dataset, tmp_path):
    """Polygons drawn on the upright image (the declared size is the upright one) load as they are; a file that
    declares the stored size was drawn on the unturned pixels and is refused, naming the tag and the fix."""
    _to_coco(synth_dataset, tmp_path / "coco", list(CLASSES))
    json_path = tmp_path / "coco" / "train" / "_annotations.coco.json"
    coco = json.loads(json_path.read_text())
    entry = next(i for i in coco["images"] if any(a["image_id"] == i["id"] for a in coco["annotations"]))
    upright = _store_turned(json_path.parent / entry["file_name"])
    assert upright.shape[:2] == (entry["height"], entry["width"])
    reference = {s.image.name: s for s in load_dataset(synth_dataset).samples}[entry["file_name"]]
    loaded = {s.image.name: s for s in load_dataset(tmp_path / "coco").samples}[entry["file_name"]]
    assert load_dataset(tmp_path / "coco").errors == []
    for a, b in zip(loaded.instances, reference.instances, strict=True):
        np.testing.assert_allclose(a.polygon, b.polygon, atol=1e-6)
    entry["width"], entry["height"] = entry["height"], entry["width"]
    json_path.write_text(json.dumps(coco))
    errors = load_dataset(tmp_path / "coco").errors
    assert len(errors) == 1 and "EXIF orientation 6" in errors[0].message and "Auto-Orient" in errors[0].fix


def test_check_warns_of_an_image_stored_turned_and_fix_writes_it_upright(dataset_copy, tmp_path):
    from detector.datasets.orientation import UPRIGHT, encoded_orientation

    label = _first_labelled(dataset_copy)
    image = next((dataset_copy / "train" / "images").glob(label.stem + ".*"))
    upright = _store_turned(image)
    report = check_dataset(dataset_copy, progress=False)
    assert report.errors == []
    assert [p.path for p in report.problems if "EXIF orientation 6" in p.message] == [image]
    fixed = write_fixed_copy(report, tmp_path / "fixed") / "train" / "images" / image.name
    assert encoded_orientation(fixed.read_bytes()) == UPRIGHT
    import cv2
    rewritten = cv2.imread(str(fixed))
    assert rewritten.shape == upright.shape and np.abs(rewritten.astype(int) - upright).mean() < 2.0
    assert (fixed.parents[1] / "labels" / label.name).read_text() == label.read_text()
    assert check_dataset(tmp_path / "fixed", progress=False).problems == []


@pytest.mark.parametrize("squeeze_all", [True, False])
def test_check_warns_once_when_every_frame_is_square_as_after_a_stretching_resize(squeeze_all, dataset_copy, capsys):
    import cv2

    images = sorted(dataset_copy.glob("*/images/*"))
    for image in images if squeeze_all else images[1:]:
        cv2.imwrite(str(image), cv2.resize(cv2.imread(str(image)), (640, 640)))
    report = check_dataset(dataset_copy, progress=False)
    squeezed = [p for p in report.problems if "square" in p.message]
    assert report.errors == [] and len(squeezed) == squeeze_all
    if squeeze_all:
        assert squeezed[0].severity == "warning" and squeezed[0].path == dataset_copy
        assert "(640x640)" in squeezed[0].message and "Resize" in squeezed[0].fix
        assert main(["check", str(dataset_copy)]) == 0 and "1 warning(s)" in capsys.readouterr().out


def test_write_dataset_refuses_to_overwrite(synth_dataset, tmp_path):
    out = write_dataset(tmp_path / "out", load_dataset(synth_dataset))
    with pytest.raises(FileExistsError, match="--force"):
        write_dataset(out, load_dataset(synth_dataset))
    assert write_dataset(out, load_dataset(synth_dataset), force=True) == out
    assert not list(tmp_path.glob(".out.*"))


def test_real_poles_read_clean(real_poles):
    report = check_dataset(real_poles, progress=False)
    assert report.errors == []
    assert sum(len(s.instances) for s in report.dataset.samples) == 14


def test_check_of_a_folder_that_is_no_dataset_prints_the_error_alone(tmp_path, capsys):
    """No empty per-split table above the one line that says what the folder lacks."""
    assert main(["check", str(tmp_path)]) == 1
    out = capsys.readouterr().out
    assert "neither data.yaml nor a COCO" in out
    assert "split" not in out and "images" not in out


def test_an_output_inside_the_folder_data_yaml_path_names_is_refused_even_with_force(synth_dataset, tmp_path, capsys):
    """data.yaml's `path:` makes its folder an input: nothing may be written, or replaced, inside it."""
    elsewhere = tmp_path / "elsewhere"
    shutil.copytree(synth_dataset, elsewhere)
    (elsewhere / "mydocs").mkdir()
    (elsewhere / "mydocs" / "thesis.txt").write_text("four years of work")
    pointer = tmp_path / "pointer"
    pointer.mkdir()
    config = yaml.safe_load((synth_dataset / "data.yaml").read_text())
    (pointer / "data.yaml").write_text(yaml.safe_dump({**config, "path": "../elsewhere"}))
    assert main(["convert", str(pointer), "--out", str(elsewhere / "mydocs"), "--force"]) == 2
    assert "elsewhere" in capsys.readouterr().err
    assert (elsewhere / "mydocs" / "thesis.txt").read_text() == "four years of work"
