"""The thread tuner keeps the thread count that trains fastest, on an idle machine and on a busy one."""
from __future__ import annotations

import pytest

import detector.training.cpu_threads as cpu_threads
from detector.training.cpu_threads import ThreadTuner


@pytest.mark.parametrize("seconds_per_batch, expected", [({1: 2.1, 2: 1.1}, 2),   # idle: two threads help
                                                         ({1: 2.3, 2: 3.3}, 1)])  # beside a CPU hog: one is faster
def test_tuner_settles_on_the_faster_thread_count(seconds_per_batch, expected, monkeypatch):
    state = {"threads": 2, "clock": 0.0}
    monkeypatch.setattr(cpu_threads.torch, "set_num_threads", lambda n: state.__setitem__("threads", n))
    monkeypatch.setattr(cpu_threads.torch, "get_num_threads", lambda: state["threads"])
    monkeypatch.setattr(cpu_threads.time, "perf_counter", lambda: state["clock"])
    tuner = ThreadTuner(most=2, probe_every=6, window=3)
    kept = []
    for _ in range(60):
        state["clock"] += seconds_per_batch[state["threads"]]
        tuner()
        kept.append(tuner.threads)
    assert tuner.threads == expected and kept[-20:] == [expected] * 20
    assert len(tuner.history) >= 3  # it keeps probing, so it follows a load that comes and goes


def test_tuner_follows_a_load_that_arrives(monkeypatch):
    state = {"threads": 2, "clock": 0.0}
    monkeypatch.setattr(cpu_threads.torch, "set_num_threads", lambda n: state.__setitem__("threads", n))
    monkeypatch.setattr(cpu_threads.torch, "get_num_threads", lambda: state["threads"])
    monkeypatch.setattr(cpu_threads.time, "perf_counter", lambda: state["clock"])
    tuner = ThreadTuner(most=2, probe_every=6, window=3)
    for batch in range(120):
        busy = batch >= 40
        state["clock"] += {1: 2.3, 2: 3.3}[state["threads"]] if busy else {1: 2.1, 2: 1.1}[state["threads"]]
        tuner()
        if batch == 39:
            assert tuner.threads == 2
    assert tuner.threads == 1


def test_shared_machine_wait_policy_is_set_only_before_torch_loads():
    """libgomp reads OMP_WAIT_POLICY once, when torch loads it: after that the request must say it came too late."""
    import os
    import subprocess
    import sys

    code = ("import os; from detector.training.openmp_wait import sleep_while_waiting; first = sleep_while_waiting(); "
            "policy = os.environ.pop('OMP_WAIT_POLICY', None); import torch; "
            "print(first, policy, sleep_while_waiting(), os.environ.get('OMP_WAIT_POLICY'))")
    env = {k: v for k, v in os.environ.items() if k != "OMP_WAIT_POLICY"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env)
    assert out.stdout.split() == ["True", "PASSIVE", "False", "None"]


def test_threads_option_accepts_counts_shared_all_and_auto():
    from detector.cli import build_parser

    parse = build_parser().parse_args
    train = ["train", "--data", "d", "--out", "o", "--threads"]
    assert [parse([*train, t]).threads for t in ("2", "shared", "all", "auto")] == [2, "shared", "all", "auto"]
    assert [parse(["demo", "--threads", t]).threads for t in ("shared", "all")] == ["shared", "all"]


@pytest.mark.parametrize("argv, policy", [(["train", "--data", "d", "--out", "o"], "PASSIVE"),
                                          (["train", "--data", "d", "--out", "o", "--threads", "shared"], "PASSIVE"),
                                          (["train", "--data", "d", "--out", "o", "--threads", "all"], "None"),
                                          (["demo"], "PASSIVE"), (["demo", "--threads", "all"], "None")])
def test_waiting_threads_sleep_unless_told_all(argv, policy):
    """What the command sets before torch loads: sleeping threads by default, libgomp's spinning for `all`."""
    import os
    import subprocess
    import sys

    code = ("import os, sys; from detector.cli import build_parser; "
            "from detector.training.openmp_wait import choose_wait_policy; "
            f"choose_wait_policy(build_parser().parse_args({argv!r}).threads); "
            "print('torch' in sys.modules, os.environ.get('OMP_WAIT_POLICY'))")
    env = {k: v for k, v in os.environ.items() if k != "OMP_WAIT_POLICY"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env)
    assert out.stdout.split() == ["False", policy]
