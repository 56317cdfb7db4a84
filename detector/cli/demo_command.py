"""``poles demo``: the whole pipeline on a synthetic dataset, ending in ``report.html``."""
from __future__ import annotations

import argparse
from pathlib import Path

from detector.cli.arguments import minutes_number, whole_number
from detector.training.openmp_wait import choose_wait_policy


def add_parsers(sub: argparse._SubParsersAction) -> None:
    """Add the `demo` command to ``sub`` (``run``: the function that runs it)."""
    demo = sub.add_parser("demo", help="run the whole pipeline on a synthetic dataset and write report.html")
    demo.add_argument("--out", type=Path, default=Path("runs/demo"))
    demo.add_argument("--budget", choices=("fast", "full"), default="fast",
                      help="fast: about 15 minutes on two cores (default); full: the thesis's settings (days)")
    demo.add_argument("--minutes", type=minutes_number,
                      help="the whole run's time on this machine with the fast budget (default 12): training gets "
                           "what the other stages leave")
    demo.add_argument("--seed", type=whole_number(0), default=0)
    demo.add_argument("--threads", choices=("shared", "all"),
                      help="shared (default): every core, waiting threads sleep, so other programs do not slow "
                           "training down many times over; all: every core, waiting threads spin (about 10 %% faster "
                           "on an idle machine)")
    demo.set_defaults(run=_demo)


def _demo(args: argparse.Namespace) -> int:
    choose_wait_policy(args.threads)
    from detector.demo.budget import BUDGETS
    from detector.demo.pipeline import run_demo

    budget = BUDGETS[args.budget]
    return run_demo(args.out, budget.with_minutes(args.minutes) if args.minutes else budget, args.seed)
