"""The process pool behind rendering and augmentation: order kept, and workers that die plainly on SIGTERM."""
from __future__ import annotations

import signal

from detector.errors import run_command
from detector.parallel import ordered_map


def _square(x: int) -> int:
    return x * x


def _sigterm_is_default(_: int) -> bool:
    return signal.getsignal(signal.SIGTERM) == signal.SIG_DFL and signal.getsignal(signal.SIGINT) == signal.SIG_IGN


def test_results_come_back_in_order_with_and_without_workers():
    assert list(ordered_map(_square, range(20), workers=2)) == [x * x for x in range(20)]
    assert list(ordered_map(_square, range(5), workers=1)) == [0, 1, 4, 9, 16]


def test_workers_do_not_inherit_the_commands_sigterm_handler():
    """Inside a command SIGTERM raises (to clean up); a pool worker that inherited that would be able to die holding
    the task queue's lock when the pool is terminated, and hang the command."""
    seen = []

    def command() -> int:
        assert signal.getsignal(signal.SIGTERM) not in (signal.SIG_DFL, None)
        seen.extend(ordered_map(_sigterm_is_default, range(8), workers=2))
        return 0

    assert run_command("test", command) == 0
    assert seen == [True] * 8
