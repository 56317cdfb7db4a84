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
