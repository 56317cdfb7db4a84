"""OpenMP's wait policy for a shared machine, set before torch loads its OpenMP runtime.

torch's intra-op threads spin while they wait for each other (libgomp's default), which is fastest on idle cores.
Beside another program at the same priority a spinning thread burns the time slice its descheduled partner needs,
and two threads end up slower than one. ``OMP_WAIT_POLICY=PASSIVE`` makes waiting threads sleep instead
(``benchmarks/bench_busy_train.py``, two clean runs: beside one CPU hog 4.3 -> 6.4 and 4.2 -> 6.0 images/s, idle
11.4 -> 10.4 and 10.8 -> 9.8), so ``poles train`` and ``poles demo`` sleep by default. libgomp reads the policy
once, when it is loaded, so it can only be chosen before the first ``import torch``.
"""
from __future__ import annotations

import os
import sys


def sleep_while_waiting() -> bool:
    """Ask OpenMP threads to sleep while they wait; False (and nothing set) when torch is already loaded."""
    if "torch" in sys.modules:
        return False
    os.environ["OMP_WAIT_POLICY"] = "PASSIVE"
    return True


def choose_wait_policy(threads: int | str | None) -> None:
    """Let OpenMP threads sleep while they wait, by default (None) and for ``--threads shared``; must run before
    torch loads. Only an explicit ``--threads shared`` says so when it came too late (a caller that loaded torch)."""
    if threads not in (None, "shared"):
        return
    if not sleep_while_waiting() and threads == "shared":
        print("--threads shared: torch was loaded already, OpenMP keeps its wait policy", file=sys.stderr)
