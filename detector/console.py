"""What a command shows on the terminal: the one rich console for tables and messages, and its progress bars."""
from __future__ import annotations

import os
import sys
from collections.abc import Iterable, Iterator
from typing import TypeVar

from rich.console import Console
from tqdm import tqdm

LOG_WIDTH = 160
#: Into a log, a progress bar writes one line at most this often (seconds).
LOG_PROGRESS_INTERVAL_S = 30.0

T = TypeVar("T")


def make_console() -> Console:
    """A rich console; into a file or a pipe (a CI log, ``| tee``) 160 columns wide rather than rich's 80.

    At 80 columns rich cuts a table's headers to a letter or two and breaks a problem's path across lines, which
    is what a log keeps. ``COLUMNS`` in the environment still wins.
    """
    console = Console()
    if not console.is_terminal and "COLUMNS" not in os.environ:
        console.width = LOG_WIDTH
    return console


def show_progress(items: Iterable[T], desc: str, unit: str, total: int | None = None, enabled: bool = True,
                  leave: bool = True) -> Iterator[T]:
    """``items`` with a tqdm bar on stderr: live on a terminal (``leave=False`` clears it at the end); into a file or
    a pipe one whole line every 30 seconds and one at the end, always kept, where tqdm's carriage returns would pile
    every update into one line of the log."""
    if sys.stderr.isatty():
        return iter(tqdm(items, desc=desc, unit=unit, total=total, disable=not enabled, leave=leave))
    return iter(tqdm(items, desc=desc, unit=unit, total=total, disable=not enabled, ascii=True,
                     mininterval=LOG_PROGRESS_INTERVAL_S, bar_format="{l_bar}{bar}{r_bar}\n"))
