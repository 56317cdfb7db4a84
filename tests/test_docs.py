"""The README and docs/ name only commands, flags and runtime names that exist: a rename fails here, not on a robot."""
from __future__ import annotations

import argparse
import re
import shlex

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
