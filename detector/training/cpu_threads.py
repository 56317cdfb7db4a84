"""Keep CPU training fast when other programs share the cores: pick torch's thread count by measuring it.

Each torch operator splits its work over the intra-op threads and waits for all of them. On an idle machine every
core helps; when other processes want the same cores, one thread of the team is often descheduled and the rest wait
for it at every operator, so two threads can be slower than one. ``ThreadTuner`` does not guess the load: every
``probe_every`` batches it times a few batches at another thread count and keeps whichever was faster.
"""
from __future__ import annotations

import statistics
import time

import torch


class ThreadTuner:
    """An Ultralytics ``on_train_batch_end`` callback that hill-climbs torch's thread count between 1 and ``most``."""

    def __init__(self, most: int, probe_every: int = 30, window: int = 3):
        self.most = max(1, most)
        self.probe_every, self.window = probe_every, window
        self.threads = torch.get_num_threads()
        self.best: float | None = None  # median batch time of the kept thread count
        self.trial: int | None = None  # the thread count on trial, if a probe is running
        self.times: list[float] = []
        self.batches_since_probe = 0
        self.last: float | None = None
        self.history: list[tuple[int, float]] = []  # (threads kept, median batch seconds) after each decision
        self.step = -1  # the direction of the next probe: fewer threads first

    def __call__(self, trainer=None) -> None:
        now = time.perf_counter()
        previous, self.last = self.last, now
        if previous is None:  # the first batch includes warm-up
            return
        self.times.append(now - previous)
        if len(self.times) < self.window:
            return
        median = statistics.median(self.times)
        self.times = []
        if self.trial is not None:
            self._decide(median)
        elif self.best is None:
            self.best = median
            self._start_probe()
        else:
            self.best = median if self.batches_since_probe < self.window else 0.5 * (self.best + median)
            self.batches_since_probe += self.window
            if self.batches_since_probe >= self.probe_every:
                self._start_probe()

    def _start_probe(self) -> None:
        if self.most == 1:
            return
        if not 1 <= self.threads + self.step <= self.most:
            self.step = -self.step
        self.trial = self.threads + self.step
        self.step = -self.step
        torch.set_num_threads(self.trial)

    def _decide(self, trial_median: float) -> None:
        if trial_median < self.best:
            self.threads, self.best = self.trial, trial_median
        torch.set_num_threads(self.threads)
        self.history.append((self.threads, self.best))
        self.trial, self.batches_since_probe = None, 0
