"""The process pool behind rendering and augmentation: order kept, and workers that die plainly on SIGTERM."""
from __future__ import annotations

import signal
import subprocess
import sys
import textwrap

from detector.errors import run_command
from detector.parallel import ordered_map
from naoslam.shipped import shipped_path


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


def _held_at_start_and_now(_: int) -> tuple[bool, bool]:
    return _held_at_start, signal.SIGTERM in signal.pthread_sigmask(signal.SIG_BLOCK, [])


_held_at_start = None


def test_a_worker_holds_sigterm_until_it_takes_it_plainly(monkeypatch):
    """``terminate()`` may signal a worker that has not run a line since its fork: the signal must wait for the
    default handler (and then kill it), never meet the parent's raising one."""
    import detector.parallel as parallel

    set_up = parallel._plain_signals

    def recording_set_up() -> None:
        global _held_at_start
        _held_at_start = signal.SIGTERM in signal.pthread_sigmask(signal.SIG_BLOCK, [])
        set_up()

    monkeypatch.setattr(parallel, "_plain_signals", recording_set_up)
    before = signal.pthread_sigmask(signal.SIG_BLOCK, [])
    assert set(ordered_map(_held_at_start_and_now, range(8), workers=2)) == {(True, False)}
    assert signal.pthread_sigmask(signal.SIG_BLOCK, []) == before  # the parent's mask is given back


def test_a_forked_worker_never_destroys_an_onnxruntime_session_the_parent_left_to_the_collector():
    """Destroying an onnxruntime session in a forked worker waits for thread-pool threads that were not forked:
    forever. A session in a reference cycle is freed by the garbage collector, whenever it runs next; this once
    hung `poles demo` when a rendering worker's first collection met the evaluation stage's sessions."""
    code = textwrap.dedent(f"""
        import gc, sys
        import onnxruntime
        from detector.parallel import ordered_map
        gc.disable()  # keep the garbage until the pool forks, as a parent between collections would
        cycle = [onnxruntime.InferenceSession({str(shipped_path(False))!r}, providers=["CPUExecutionProvider"])]
        cycle.append(cycle)
        del cycle
        print(list(ordered_map(gc.collect, [2, 2], workers=2)))
    """)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
