"""How many cores this process may run on: the ones its CPU affinity allows (``taskset``, a container's cpuset, a
test worker pinned to one core), not every core the machine has."""
from __future__ import annotations

import os


def usable_cores() -> int:
    """The cores this process may use (at least 1)."""
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return os.cpu_count() or 1
