"""How a ``poles`` command ends: one line on standard error for anything that goes wrong, never a raw traceback.

Bad input (a dataset problem, a file that is missing, exists or cannot be written, a bad value) exits 2 with the
message, which names the file and the fix. Ctrl-C and SIGTERM exit 130 / 143 after the atomic writers have removed
their partial output. A stage of a resumable run (``detector.stages``) that fails says which stage, why, and that
the stages before it are kept. Anything unexpected exits 1 with a one-line summary and the traceback saved to a log file;
``--debug`` shows the traceback instead.
"""
from __future__ import annotations

import errno
import signal
import re
import sys
import tempfile
import time
import traceback
from collections.abc import Callable
from contextlib import contextmanager
from pathlib import Path

from detector.datasets.model import BAD_INPUT_ERRORS
from detector.stages import StageFailed

#: Exit statuses.
BAD_INPUT, UNEXPECTED, INTERRUPTED, TERMINATED = 2, 1, 130, 143


class Terminated(BaseException):
    """SIGTERM, raised like Ctrl-C so that every ``with`` block cleans up on the way out."""


@contextmanager
def _sigterm_raises():
    def raise_terminated(signum, frame):
        raise Terminated

    try:
        previous = signal.signal(signal.SIGTERM, raise_terminated)
    except ValueError:  # not the main thread: leave signals alone
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


#: What an interrupted command says it did with its output, unless it said otherwise (``keep_on_interrupt``).
DEFAULT_INTERRUPT_NOTE = "unfinished output was removed"
_interrupt_note: str | None = None


def keep_on_interrupt(note: str | None) -> None:
    """Say ``note`` (what the command keeps, and how to resume it) if it is interrupted from now on (None: the
    default)."""
    global _interrupt_note
    _interrupt_note = note


#: What to do about the operating system's refusals, by errno.
_OS_FIXES = {
    errno.ENOSPC: "the disk is full - free some space or write --out to another disk; nothing was left behind",
    errno.EDQUOT: "the disk quota is full - free some space or write --out elsewhere; nothing was left behind",
    errno.EACCES: "permission denied - choose an --out in a folder you may write to",
    errno.EPERM: "permission denied - choose an --out in a folder you may write to",
    errno.EROFS: "the disk is read-only - choose an --out on a writable disk",
    errno.ENOTDIR: "a file stands where a folder is needed - choose an --out inside a folder",
    errno.EEXIST: "a file stands where a folder is needed - choose another --out",
}


def os_error_message(error: OSError) -> str:
    """One line for an operating-system error: the user's path (not the hidden temporary folder an atomic write
    used) and what to do; errors raised with a message of this project's own are kept as they are."""
    if error.errno not in _OS_FIXES or error.filename is None:
        return str(error)
    return f"{_user_path(Path(error.filename))}: {_OS_FIXES[error.errno]}"


#: The end of the temporary file's name an atomic write makes beside its output, ``.<name>.<pid>.tmp``
#: (``detector.atomic.atomic_path``).
_TEMPORARY_SUFFIX = re.compile(r"^(.+)\.\d+\.tmp$")


def _user_path(path: Path) -> Path:
    """The output an atomic writer's temporary ``.<name>.partial-XXXX`` folder or ``.<name>.<pid>.tmp`` file (one in
    another, too) stands for, else ``path``."""
    for part in (path, *path.parents):
        if part.name.startswith(".") and ".partial-" in part.name:
            return part.parent / part.name[1:].split(".partial-")[0]
    name = path.name
    if not (name.startswith(".") and _TEMPORARY_SUFFIX.match(name)):
        return path
    name = name.lstrip(".")
    while match := _TEMPORARY_SUFFIX.match(name):
        name = match.group(1)
    return path.with_name(name)


def run_command(name: str, command: Callable[[], int], debug: bool = False) -> int:
    """Run ``command`` and turn whatever it raises into a message and an exit status."""
    prefix = f"poles {name}:"
    try:
        with _sigterm_raises():
            return command()
    except KeyboardInterrupt:
        print(f"{prefix} interrupted; {_interrupt_note or DEFAULT_INTERRUPT_NOTE}", file=sys.stderr)
        return INTERRUPTED
    except Terminated:
        print(f"{prefix} terminated; {_interrupt_note or DEFAULT_INTERRUPT_NOTE}", file=sys.stderr)
        return TERMINATED
    except BAD_INPUT_ERRORS as exc:
        if debug:
            raise
        print(f"{prefix} {os_error_message(exc) if isinstance(exc, OSError) else exc}", file=sys.stderr)
        return BAD_INPUT
    except StageFailed as exc:
        if debug:
            raise
        print(f"{prefix} {exc}", file=sys.stderr)
        return BAD_INPUT if isinstance(exc.__cause__, BAD_INPUT_ERRORS) else UNEXPECTED
    except Exception as exc:
        if debug:
            raise
        log = Path(tempfile.gettempdir()) / f"poles-{name}-{time.strftime('%Y%m%d-%H%M%S')}.log"
        log.write_text(traceback.format_exc(), encoding="utf-8")
        summary = str(exc).splitlines()[0][:200] if str(exc) else ""
        print(f"{prefix} unexpected error: {type(exc).__name__}: {summary}\n  details: {log} "
              f"(rerun with --debug to see the traceback)", file=sys.stderr)
        return UNEXPECTED
