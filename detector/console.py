"""What a command shows on the terminal: the one rich console for tables and messages, and its progress bars."""
from __future__ import annotations

import math
import os
import sys
import time
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from typing import TextIO, TypeVar

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


def redraws_in_place(stream: TextIO) -> bool:
    """True for a terminal and for a notebook's output area: both draw a carriage return over the line."""
    return stream.isatty() or type(stream).__module__.startswith("ipykernel")


def show_progress(items: Iterable[T], desc: str, unit: str, total: int | None = None, enabled: bool = True,
                  leave: bool = True) -> Iterator[T]:
    """``items`` with a tqdm bar on stderr: live on a terminal or in a notebook (``leave=False`` clears it at the end);
    into a file or a pipe one whole line every 30 seconds and one at the end, always kept, where tqdm's carriage
    returns would pile every update into one line of the log."""
    if redraws_in_place(sys.stderr):
        return iter(tqdm(items, desc=desc, unit=unit, total=total, disable=not enabled, leave=leave))
    return iter(tqdm(items, desc=desc, unit=unit, total=total, disable=not enabled, ascii=True,
                     mininterval=LOG_PROGRESS_INTERVAL_S, bar_format="{l_bar}{bar}{r_bar}\n"))


class LogBarStream:
    """Stands in for stdout while Ultralytics trains into a file or a pipe (a background run's log, ``| tee``).

    Ultralytics' progress bars hand every redraw to their stream's ``progress(bar, frame)`` when it has one (the
    hook its own ``ConsoleLogger`` uses), and ``progress(bar, "")`` when the bar closes. Here a bar writes one whole
    line every 30 seconds and its last frame when it closes, where each redraw (ten a second) would otherwise be
    appended to one ever longer line of the log. Everything else passes through unchanged.
    """

    def __init__(self, stream: TextIO, interval_s: float = LOG_PROGRESS_INTERVAL_S,
                 clock: Callable[[], float] = time.monotonic):
        self.stream = stream
        self.interval_s = interval_s
        self.clock = clock
        self._shown_at: dict[int, float] = {}
        self._unshown: dict[int, str] = {}
        self._closed_frame: str | None = None

    def progress(self, bar: int, frame: str) -> None:
        """One redraw of ``bar``; an empty frame closes it."""
        frame = frame.rsplit("\r", 1)[-1].replace("\x1b[K", "")
        if not frame:
            self._shown_at.pop(bar, None)
            self._closed_frame = self._unshown.pop(bar, "")
            return
        now = self.clock()
        if now - self._shown_at.get(bar, -math.inf) >= self.interval_s:
            self.stream.write(frame + "\n")
            self._shown_at[bar] = now
            self._unshown.pop(bar, None)
        else:
            self._unshown[bar] = frame

    def write(self, text: str) -> int:
        """Pass ``text`` on; right after a bar closed, its ending (a newline, or a clear for a bar not kept) ends the
        bar's last frame instead."""
        closed, self._closed_frame = self._closed_frame, None
        if closed is not None and text in ("\n", "\r\x1b[K"):
            if closed and text == "\n":
                self.stream.write(closed + "\n")
            return len(text)
        if closed:
            self.stream.write(closed + "\n")
        return self.stream.write(text)

    def __getattr__(self, name: str):
        return getattr(self.stream, name)


@contextmanager
def bars_as_log_lines() -> Iterator[None]:
    """While inside, Ultralytics' progress bars write whole lines every 30 s into a file or a pipe (a terminal or
    a notebook keeps its live bar)."""
    if redraws_in_place(sys.stdout):
        yield
        return
    original = sys.stdout
    sys.stdout = LogBarStream(original)
    try:
        yield
    finally:
        sys.stdout = original
