"""Nothing a user owns is ever lost: the one output rule (``detector.outputs``) on every command that writes, each
case hashing what it must not touch before and after."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from detector.atomic import write_json
from detector.cli import main
from detector.errors import keep_on_interrupt, os_error_message, run_command
from detector.outputs import OUTPUT_MARKER, fresh_path
from tests.test_bad_input import set_yaml, tree_hash


@pytest.fixture
def victim(synth_dataset, tmp_path) -> Path:
    """A dataset poles rendered (so it carries poles's record), which the user has since added notes to."""
    folder = Path(shutil.copytree(synth_dataset, tmp_path / "victim"))
    (folder / "mydocs").mkdir()
    (folder / "mydocs" / "notes.txt").write_text("the user's own notes")
    return folder


@pytest.fixture
def pointing(victim, tmp_path) -> Path:
    """A dataset whose data.yaml's ``path:`` names the victim as its image root (Ultralytics' key)."""
    folder = tmp_path / "d"
    folder.mkdir()
    for name in ("data.yaml", "annotations.json"):
        shutil.copyfile(victim / name, folder / name)
    set_yaml(folder, path="../victim")
    return folder


def _refused(argv: list[str], guarded: Path, capsys, says: str) -> str:
    before = tree_hash(guarded)
    status = main(argv)
    error = capsys.readouterr().err
    assert status == 2, error
    assert says in error and "Traceback" not in error, error
    assert tree_hash(guarded) == before
    return error


@pytest.mark.parametrize("out", ["victim", "victim/ev"])
def test_evaluate_never_writes_into_the_image_root_data_yaml_names(out, pointing, victim, tmp_path, capsys):
    _refused(["evaluate", str(pointing), "--model", "colour-filter", "--out", str(tmp_path / out), "--force"],
             victim, capsys, "overlaps the input")


def test_calibrate_never_writes_into_the_image_root_data_yaml_names(pointing, victim, tmp_path, capsys):
    _refused(["calibrate", str(pointing), "--out", str(victim / "cal" / "c.json")], victim, capsys,
             "overlaps the input")
    assert not (victim / "cal").exists()


def test_finetune_refused_inside_its_export_leaves_no_run_folder(pointing, victim, tmp_path, capsys):
    _refused(["finetune", str(pointing), "--out", str(victim / "runs")], victim, capsys, "overlaps the input")
    assert not (victim / "runs").exists()


def test_finetune_on_an_export_without_training_frames_says_why_in_one_line_and_leaves_nothing(synth_dataset,
                                                                                               tmp_path, capsys):
    export = Path(shutil.copytree(synth_dataset, tmp_path / "export"))
    shutil.rmtree(export / "train")
    error = _refused(["finetune", str(export), "--out", str(tmp_path / "run")], export, capsys, "train")
    assert "ValueError" not in error
    assert not (tmp_path / "run").exists()


def test_synth_refuses_an_out_inside_another_dataset(victim, capsys):
    _refused(["synth", "--images", "2", "--workers", "1", "--out", str(victim / "train" / "images" / "sub")],
             victim, capsys, "lies inside the dataset")


def test_force_replaces_only_poles_s_output_of_the_same_kind(victim, synth_dataset, tmp_path, capsys):
    """The victim holds poles's dataset record: an evaluation may not replace it, and neither may a synth while
    the user's notes are in it."""
    _refused(["evaluate", str(synth_dataset), "--model", "colour-filter", "--out", str(victim), "--force"],
             victim, capsys, "not a evaluation")
    _refused(["synth", "--images", "2", "--workers", "1", "--out", str(victim), "--force"], victim, capsys,
             "mydocs/notes.txt")
    (victim / "mydocs" / "notes.txt").unlink()
    (victim / "mydocs").rmdir()
    assert main(["synth", "--images", "2", "--workers", "1", "--out", str(victim), "--force"]) == 0
    record = json.loads((victim / OUTPUT_MARKER).read_text())
    assert record["kind"] == "dataset" and "data.yaml" in record["files"]


@pytest.mark.parametrize("command", ["evaluate", "convert", "synth"])
def test_force_keeps_a_users_file_beside_an_earlier_release_s_plain_marker(command, synth_dataset, tmp_path,
                                                                             capsys):
    """The previous release's marker lists no files, so nothing in the folder is known to be poles's: refused."""
    old = tmp_path / "old-output"
    old.mkdir()
    (old / OUTPUT_MARKER).write_text("written by poles; --force may replace this folder")
    (old / "my_thesis.txt").write_text("the user's thesis")
    argv = {"evaluate": ["evaluate", str(synth_dataset), "--model", "colour-filter"],
            "convert": ["convert", str(synth_dataset)],
            "synth": ["synth", "--images", "2", "--workers", "1"]}[command]
    error = _refused([*argv, "--out", str(old), "--force"], old, capsys, "my_thesis.txt")
    first = next(line for line in error.splitlines() if line.startswith(f"poles {command}:"))
    assert "lists no files" in first


def test_force_replaces_an_earlier_release_s_folder_that_holds_only_its_marker(synth_dataset, tmp_path):
    old = tmp_path / "old-output"
    old.mkdir()
    (old / OUTPUT_MARKER).write_text("written by poles; --force may replace this folder")
    assert main(["convert", str(synth_dataset), "--out", str(old), "--force"]) == 0
    assert (old / "data.yaml").is_file()


def test_check_never_replaces_a_file_of_the_users_in_the_working_folder(dataset_copy, tmp_path, monkeypatch,
                                                                       capsys):
    for label in sorted((dataset_copy / "train" / "labels").glob("*.txt")):
        label.write_text(label.read_text() + "".join("9 0.1 0.1 0.2 0.2 0.3 0.1\n" for _ in range(3)))
    here = tmp_path / "work"
    here.mkdir()
    mine = here / f"check-{dataset_copy.name}.txt"
    mine.write_text("my own file")
    monkeypatch.chdir(here)
    assert main(["check", str(dataset_copy)]) == 1
    assert mine.read_text() == "my own file"
    written = here / f"check-{dataset_copy.name}-2.txt"
    assert written.is_file() and written.name in capsys.readouterr().out.replace("\n", "")


def test_a_fresh_path_never_names_an_existing_file(tmp_path):
    first = tmp_path / "report.txt"
    assert fresh_path(first) == first
    first.write_text("x")
    (tmp_path / "report-2.txt").write_text("y")
    assert fresh_path(first) == tmp_path / "report-3.txt"


def test_an_interrupted_resumable_command_says_what_it_kept_and_how_to_resume(capsys):
    def interrupted() -> int:
        keep_on_interrupt("the finished stages are kept in runs/mine: run the same command again to resume")
        raise KeyboardInterrupt

    assert run_command("finetune", interrupted) == 130
    error = capsys.readouterr().err
    assert "kept in runs/mine" in error and "removed" not in error
    keep_on_interrupt(None)


def test_a_temporary_file_in_an_os_error_is_named_as_the_output_it_stands_for():
    import errno
    import os

    error = PermissionError(errno.EACCES, os.strerror(errno.EACCES), "/robot/models/.m.onnx.20816.tmp.20816.tmp")
    assert os_error_message(error).startswith("/robot/models/m.onnx: permission denied")


def test_split_ratios_of_nothing_say_so(dataset_copy, tmp_path, capsys):
    _refused(["split", str(dataset_copy), "--out", str(tmp_path / "out"), "--ratios", "0", "0", "0"], dataset_copy,
             capsys, "puts every image nowhere")


def test_an_unreadable_label_file_is_fixed_with_chmod(tmp_path, monkeypatch):
    from detector.datasets.labels import parse_label_file

    label = tmp_path / "a.txt"
    label.write_text("0 0.1 0.1 0.2 0.2 0.3 0.1\n")

    def refuse(self, *args, **kwargs):
        raise PermissionError(13, "Permission denied", str(self))

    monkeypatch.setattr(Path, "read_text", refuse)
    _, problems = parse_label_file(label, ("bp",))
    assert "chmod u+r" in problems[0].fix


def test_an_annotations_json_of_another_shape_is_named_not_silently_ignored(dataset_copy, tmp_path, capsys):
    names = [p.name for p in sorted((dataset_copy / "test" / "images").glob("*.jpg"))]
    (dataset_copy / "annotations.json").write_text(json.dumps({"images": {name: "oops" for name in names}}))
    assert main(["evaluate", str(dataset_copy), "--model", "colour-filter", "--out", str(tmp_path / "ev")]) == 0
    assert "their truth is ignored" in capsys.readouterr().out


def test_an_annotations_json_for_other_images_is_named_not_silently_ignored(dataset_copy, tmp_path, capsys):
    (dataset_copy / "annotations.json").write_text(json.dumps({"images": {"x.jpg": {"landmarks": []}}}))
    assert main(["evaluate", str(dataset_copy), "--model", "colour-filter", "--out", str(tmp_path / "ev")]) == 0
    printed = capsys.readouterr().out
    assert "names none of the dataset's" in printed and "x.jpg" in printed


def test_check_in_a_folder_it_cannot_write_keeps_its_list_in_the_temporary_folder(dataset_copy, tmp_path,
                                                                                   monkeypatch, capsys):
    """A list the working folder cannot take goes to the system's temporary folder, and the line says where."""
    import os
    import tempfile

    from detector.datasets import check

    for label in sorted((dataset_copy / "train" / "labels").glob("*.txt")):
        label.write_text(label.read_text() + "".join("9 0.1 0.1 0.2 0.2 0.3 0.1\n" for _ in range(3)))
    here = tmp_path / "read-only"
    here.mkdir()
    monkeypatch.chdir(here)
    monkeypatch.setattr(check.os, "access", lambda path, mode: Path(path).resolve() != here.resolve())
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "temporary"))
    os.makedirs(tmp_path / "temporary")
    assert main(["check", str(dataset_copy)]) == 1
    written = tmp_path / "temporary" / f"check-{dataset_copy.name}.txt"
    assert written.is_file() and not any(here.iterdir())
    assert str(written) in capsys.readouterr().out.replace("\n", "")


def test_every_json_file_is_strict_json_with_null_where_a_figure_is_not_finite(tmp_path):
    """``Infinity`` and ``NaN`` are not JSON: strict readers such as jq refuse a file that holds them."""
    path = write_json(tmp_path / "figures.json", {"f1": float("nan"), "minutes": [1.5, float("inf")],
                                                  "nested": {"low": -float("inf"), "pair": (2.0, "x")}})

    def refuse(name: str):
        raise ValueError(f"not strict JSON: {name}")

    assert json.loads(path.read_text(), parse_constant=refuse) == {
        "f1": None, "minutes": [1.5, None], "nested": {"low": None, "pair": [2.0, "x"]}}
