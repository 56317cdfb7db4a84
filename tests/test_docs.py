"""The README and docs/ name only commands, flags and runtime names that exist: a rename fails here, not on a robot."""
from __future__ import annotations

import argparse
import re
import shlex
import shutil
from pathlib import Path

import pytest

import naoslam
from detector.cli import build_parser
from tests.conftest import REPOSITORY

DOCUMENTS = [REPOSITORY / "README.md", *sorted((REPOSITORY / "docs").glob("*.md"))]


def _commands() -> dict[str, argparse.ArgumentParser]:
    action = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


def _code_block_command_lines(text: str) -> list[str]:
    """Every ``poles ...`` line inside a fenced code block, its backslash continuations joined."""
    lines, inside, pending = [], False, ""
    for raw in text.splitlines():
        if raw.strip().startswith("```"):
            inside = not inside
        elif inside and raw.rstrip().endswith("\\"):
            pending += raw.rstrip()[:-1] + " "
        elif inside:
            line, pending = (pending + raw).strip(), ""
            if line.startswith("poles "):
                lines.append(line)
    return lines


def _unknown_flags(text: str) -> list[str]:
    """``poles COMMAND --flag`` pairs in ``text`` whose flag that command does not have."""
    commands = _commands()
    unknown = []
    for match in re.finditer(r"poles ([a-z]+)((?: +[^ `\n|#]+)*)", text):
        parser = commands.get(match.group(1))
        if parser is None:  # prose such as "poles v3 makes ..."
            continue
        options = {flag for action in parser._actions for flag in action.option_strings}
        unknown += [f"poles {match.group(1)} {flag}" for flag in re.findall(r"(?<![\w-])--[a-z0-9][a-z0-9-]*",
                                                                            match.group(2)) if flag not in options]
    return unknown


@pytest.mark.parametrize("document", DOCUMENTS, ids=lambda path: path.name)
def test_every_flag_the_docs_give_a_command_is_one_of_its_options(document):
    assert _unknown_flags(document.read_text(encoding="utf-8")) == []


def test_a_stale_flag_in_prose_or_a_table_is_caught():
    text = "fine-tune with `poles train DATA --out RUN --epoch 3` | or `poles evaluate --model m --split test`"
    assert _unknown_flags(text) == ["poles train --epoch"]


def test_the_readme_quick_start_and_walk_throughs_parse():
    lines = _code_block_command_lines((REPOSITORY / "README.md").read_text(encoding="utf-8"))
    assert len(lines) >= 10  # the student's and the robot team's walk-throughs
    parser = build_parser()
    for line in lines:
        parser.parse_args(shlex.split(line, comments=True)[1:])  # argparse exits (a test error) on a bad flag


def test_the_readme_lists_exactly_the_runtime_names_a_robot_program_imports():
    text = (REPOSITORY / "README.md").read_text(encoding="utf-8")
    listed = re.search(r"`naoslam.__all__` lists them: (.+?)\.\n", text, re.S).group(1)
    assert sorted(re.findall(r"`(\w+)`", listed)) == sorted(naoslam.__all__)


def _readme_walk_through(heading: str) -> list[str]:
    """The `poles` lines of the README's first code block under ``heading``, in order."""
    text = (REPOSITORY / "README.md").read_text(encoding="utf-8")
    section = text.split(f"## {heading}", 1)[1].split("```bash", 1)[1].split("```", 1)[0]
    return [line for line in _code_block_command_lines(f"```\n{section}```") if line.startswith("poles ")]


def _run_as_written(lines: list[str], smaller: dict[str, str], export: Path, frames: Path) -> None:
    """Run each README line with ``smaller`` amounts and the test's export and frames in place of the user's."""
    from detector.cli import main

    for line in lines:
        for written, small in smaller.items():
            line = line.replace(written, small)
        line = line.replace("~/poles-export", str(export)).replace("~/new-frames", str(frames))
        assert main(shlex.split(line, comments=True)[1:]) == 0, line


def test_the_readmes_own_export_way_runs_as_written_on_a_rendered_export(synth_dataset, tmp_path, monkeypatch):
    """`poles check`, `poles finetune` and `poles predict` as the README gives them, on a small rendered export;
    only the amounts shrink (two epochs at 64 px, 10-frame rendered sets)."""
    export, frames = tmp_path / "poles-export", tmp_path / "new-frames"
    shutil.copytree(synth_dataset, export)
    shutil.copytree(synth_dataset / "valid" / "images", frames)
    monkeypatch.chdir(tmp_path)
    lines = _readme_walk_through("Your own export, start to finish")
    assert [line.split()[1] for line in lines] == ["check", "finetune", "predict"]
    _run_as_written(lines, {"--out runs/mine": "--out runs/mine --minutes 3 --epochs 2 --imgsz 64 --copies 1 "
                                               "--evaluation-frames 10"}, export, frames)
    assert (tmp_path / "runs" / "mine" / "report.html").is_file()
    assert any((tmp_path / "prelabels").rglob("*.txt"))


def test_the_readmes_stage_by_stage_way_runs_as_written_on_a_rendered_export(synth_dataset, tmp_path, monkeypatch):
    """Every command of the stage-by-stage block, in its order and with its paths, on a small rendered export; only
    the amounts shrink (one epoch at 64 px, 13 calibration shots) so that it runs in a minute."""
    export = tmp_path / "poles-export"
    shutil.copytree(synth_dataset, export)
    smaller = {"--time 1": "--epochs 1 --imgsz 64 --batch 8", "--images 195": "--images 13",
               "--data data/split": "--data data/split --imgsz 256 320"}
    monkeypatch.chdir(tmp_path)
    lines = _readme_walk_through("Stage by stage")
    assert [line.split()[1] for line in lines] == ["check", "split", "augment", "train", "export", "synth",
                                                   "calibrate", "evaluate"]
    _run_as_written(lines, smaller, export, tmp_path)
    assert (tmp_path / "models" / "poles-int8.onnx").is_file() and (tmp_path / "runs" / "eval").is_dir()
