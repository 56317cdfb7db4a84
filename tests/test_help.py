"""Every ``poles`` command's ``--help`` renders: argparse formats help with %, so a stray percent sign in a help
text ends in a traceback instead of the help a newcomer asked for."""
from __future__ import annotations

import argparse
import contextlib
import io

import pytest

from detector.cli import build_parser


def _command_names() -> list[str]:
    action = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return sorted(action.choices)


def _help_of(argv: list[str]) -> str:
    out = io.StringIO()
    with contextlib.redirect_stdout(out), pytest.raises(SystemExit) as ended:
        build_parser().parse_args(argv)
    assert ended.value.code == 0
    return out.getvalue()


def test_the_parser_has_commands():
    assert {"check", "train", "train-robot", "finetune", "evaluate", "demo"} <= set(_command_names())


@pytest.mark.parametrize("command", _command_names())
def test_every_command_help_renders(command):
    text = _help_of([command, "--help"])
    assert f"poles {command}" in text and "--debug" in text


def test_the_top_level_help_lists_every_command():
    text = _help_of(["--help"])
    assert all(command in text for command in _command_names())
