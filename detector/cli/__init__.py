"""The ``poles`` command line: one subcommand per pipeline stage.

Each module adds its commands' parsers and says which function runs each (``set_defaults(run=...)``):
``dataset_commands`` (synth, check, convert, augment, split), ``training_commands`` (train, export, soup,
calibrate), ``finetune_command``, ``evaluation_commands`` (evaluate, predict), ``slam_command`` and ``demo_command``. ``arguments`` holds
the argument types they share; ``detector.errors.run_command`` decides how every command ends. A command module
imports what its command runs (torch, Ultralytics, the pipelines) inside the function that runs it, on purpose:
``poles --help`` and a mistyped option answer in half a second instead of loading the frameworks.
"""
from __future__ import annotations

import argparse

from detector.cli import (dataset_commands, demo_command, evaluation_commands, finetune_command, robot_command,
                          slam_command, training_commands)
from detector.cli.arguments import one_dataset
from detector.cli.version import PrintVersion
from detector.errors import run_command

#: The command modules, in the order ``poles --help`` lists their commands: the pipeline's order.
COMMAND_MODULES = (dataset_commands, training_commands, robot_command, finetune_command, evaluation_commands,
                   slam_command, demo_command)


def build_parser() -> argparse.ArgumentParser:
    """The ``poles`` parser: one subparser per pipeline stage, each flag with its default in its help."""
    parser = argparse.ArgumentParser(prog="poles", description="Coloured-pole landmark detector pipeline for the Nao.")
    parser.add_argument("--version", action=PrintVersion)
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for module in COMMAND_MODULES:
        module.add_parsers(sub)
    for command in sub.choices.values():
        command.add_argument("--debug", action="store_true", help="show the traceback of an unexpected error")
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run one ``poles`` command; bad input ends in one line on stderr and exit code 2, never a traceback."""
    args = build_parser().parse_args(argv)

    def command() -> int:
        if hasattr(args, "data_option"):
            args.data = one_dataset(args)
        return args.run(args)

    return run_command(args.command, command, debug=args.debug)
