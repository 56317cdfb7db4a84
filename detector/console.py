"""The one rich console every command prints its tables and messages through."""
from __future__ import annotations

import os

from rich.console import Console

LOG_WIDTH = 160


def make_console() -> Console:
    """A rich console; into a file or a pipe (a CI log, ``| tee``) 160 columns wide rather than rich's 80.

    At 80 columns rich cuts a table's headers to a letter or two and breaks a problem's path across lines, which
    is what a log keeps. ``COLUMNS`` in the environment still wins.
    """
    console = Console()
    if not console.is_terminal and "COLUMNS" not in os.environ:
        console.width = LOG_WIDTH
    return console
