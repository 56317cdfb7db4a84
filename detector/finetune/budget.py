"""How ``poles finetune`` keeps to ``--minutes`` whatever the export's size: each unit of work is timed on this
machine at the start (decoding a frame, augmenting one, rendering one, judging one), every stage's cost is estimated
from them and the export's frame counts, and the work that scales is fitted to the minutes before training gets
what is left: fewer augmented copies and rehearsal frames for a large export, fewer judged frames for a short run.
A budget too small for the least work that still makes a fine-tune is refused before anything is written, naming the
smallest that works here."""
from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace

import cv2
import numpy as np

from detector.datasets.io import SplitCounts
from detector.datasets.model import Sample
from detector.finetune.recipe import BLEND_SHARES, FinetuneRecipe
from detector.records import JsonRecord

#: The share of the minutes the plan keeps in hand for what it cannot foresee (a busy machine, a slow disk).
MARGIN = 0.08
#: At most these shares of the minutes go to preparing (augmenting, rendering the rehearsal) and to judging
#: (choosing the blend, judging the models); training gets the rest.
PREPARING_SHARE, JUDGING_SHARE = 0.3, 0.25
#: The least work that still makes a fine-tune: judged frames per rendered set, team frames judged and scored per
#: blend, rehearsal frames, and seconds of training (the accurate model, the robot's crop network).
MIN_EVALUATION_FRAMES, MIN_TEAM_FRAMES, MIN_REHEARSAL_FRAMES = 10, 10, 20
MIN_TRAINING_S = {"yolo": 60.0, "crops": 15.0}
#: Seconds that do not scale with the frames: starting the process and its libraries, writing the report; the
#: training's own start (Ultralytics' dataset scan and model build, or cutting the crop network's crops aside);
#: exporting (FP32, INT8 and their checks for the accurate model).
FIXED_S = 15.0
TRAINING_START_S = {"yolo": 25.0, "crops": 2.0}
EXPORT_S = {"yolo": 30.0, "crops": 3.0}
#: Decodes a frame costs per pass over it when cutting crops (the candidate finder and the crops ride on it).
CROP_PASS = 1.5
#: Fine-tuned models judged beside the shipped one (the fine-tune and the chosen blend), and rendered sets.
JUDGED_MODELS, RENDERED_SETS = 3, 2


class BudgetTooSmall(ValueError):
    """``--minutes`` below the least this fine-tune needs on this machine."""


@dataclass(frozen=True)
class UnitCosts(JsonRecord):
    """Seconds of one unit of each kind of work on this machine (one process), and the processes that render and
    augment side by side."""

    decode: float
    augment: float
    render: float
    judge: float
    workers: int


@dataclass(frozen=True)
class JobPlan(JsonRecord):
    """What a fine-tune does within its minutes: the work that scales, each stage's estimated seconds (``train`` is
    what is left for training) and what was cut to fit, in words."""

    minutes: float
    #: The starting model's network (``yolo`` or ``crops``).
    network: str
    costs: UnitCosts
    copies: int
    rehearsal_frames: int
    evaluation_frames: int
    #: The team's held-out frames judged, and valid frames each blend is scored on (None: all of them).
    held_out_frames: int | None
    blend_frames: int | None
    seconds: dict[str, float]
    cuts: tuple[str, ...] = ()

    def after_training_seconds(self) -> float:
        """What the stages after training are expected to take."""
        return sum(self.seconds[name] for name in ("blend", "export", "evaluate"))


def training_minutes(plan: JobPlan, spent_minutes: float) -> float:
    """The training's time cap once ``spent_minutes`` are spent: the minutes (less the margin) left after what the
    training's start and the stages after it are expected to take; at least the least training."""
    later = (plan.seconds["training start"] + plan.after_training_seconds()) / 60
    return max(MIN_TRAINING_S[plan.network] / 60, plan.minutes * (1 - MARGIN) - spent_minutes - later)


def measure_costs(samples: list[Sample], render: Callable[[], object], judge: Callable[[np.ndarray], object],
                  augment: Callable[[Sample], object], workers: int) -> UnitCosts:
    """Time each unit of work once or twice on the export's own frames: decoding, augmenting one copy, rendering
    one rehearsal frame, judging one frame with the starting model (after one untimed call that loads it)."""
    images = [sample.image for sample in samples if sample.image is not None][:3]
    began = time.perf_counter()
    frames = [cv2.imread(str(image)) for image in images]
    decode = (time.perf_counter() - began) / max(len(images), 1)
    labelled = next((sample for sample in samples if sample.instances), samples[0])
    augment_s = _timed(lambda: augment(labelled))
    render_s = _timed(render)
    judge(frames[0])
    judge_s = min(_timed(lambda: judge(frame)) for frame in frames[:2])
    return UnitCosts(decode, augment_s, render_s, judge_s + decode, workers)


def _timed(work: Callable[[], object]) -> float:
    began = time.perf_counter()
    work()
    return time.perf_counter() - began


@dataclass(frozen=True)
class _Work:
    """The scalable work of one candidate plan."""

    copies: int
    rehearsal: int
    evaluation: int
    held_out: int
    blend: int


def plan_job(recipe: FinetuneRecipe, frames: SplitCounts, costs: UnitCosts, network: str) -> JobPlan:
    """Fit the fine-tune of an export with ``frames`` (after the valid split is made) into ``recipe.minutes``:
    judging first cut to ``JUDGING_SHARE`` of them, then preparing to ``PREPARING_SHARE``, training the rest.
    ``BudgetTooSmall`` names the least minutes that work here when even the least work does not fit."""
    budget = 60 * recipe.minutes * (1 - MARGIN)
    held_out_all = frames.test or frames.valid
    wanted = _Work(recipe.copies, recipe.rehearsal_frames(frames.train * (1 + recipe.copies)),
                   recipe.evaluation_frames, held_out_all, frames.valid)
    least = _Work(0, min(MIN_REHEARSAL_FRAMES, recipe.rehearsal_frames(frames.train)),
                  min(MIN_EVALUATION_FRAMES, recipe.evaluation_frames), min(MIN_TEAM_FRAMES, held_out_all),
                  min(MIN_TEAM_FRAMES, frames.valid))
    needed = sum(_seconds(least, frames, costs, network, recipe).values()) + MIN_TRAINING_S[network]
    if needed > budget:
        smallest = math.ceil(2 * needed / 60 / (1 - MARGIN)) / 2
        raise BudgetTooSmall(f"--minutes {recipe.minutes:g} is less than this fine-tune needs on this machine: "
                             f"at least {smallest:g} minutes for {frames.train + frames.valid + frames.test:,} frames "
                             f"(the least checking, rendering, training and judging take {needed / 60:.1f}) - give "
                             f"--minutes {smallest:g} or more")
    work = _fit_judging(wanted, least, frames, costs, network, recipe, JUDGING_SHARE * budget)
    work = _fit_preparing(work, least, frames, costs, network, recipe, PREPARING_SHARE * budget)
    seconds = _seconds(work, frames, costs, network, recipe)
    if budget - sum(seconds.values()) < MIN_TRAINING_S[network]:  # the shares left too little: the least instead
        work = least
        seconds = _seconds(work, frames, costs, network, recipe)
    seconds["train"] = round(budget - sum(seconds.values()), 1)
    return JobPlan(recipe.minutes, network, costs, work.copies, work.rehearsal, work.evaluation,
                   None if work.held_out >= held_out_all else work.held_out,
                   None if work.blend >= frames.valid else work.blend, seconds, _cuts(wanted, work, frames, recipe))


def _fit_judging(work: _Work, least: _Work, frames: SplitCounts, costs: UnitCosts, network: str,
                 recipe: FinetuneRecipe, allowed: float) -> _Work:
    """Cut the rendered judging sets, the team's judged frames and the blend's frames together, each by a quarter
    at a time down to its least, until judging fits."""
    def judging(candidate: _Work) -> float:
        seconds = _seconds(candidate, frames, costs, network, recipe)
        return seconds["blend"] + seconds["evaluate"]

    fields = ("evaluation", "held_out", "blend")
    while judging(work) > allowed and any(getattr(work, f) > getattr(least, f) for f in fields):
        work = replace(work, **{f: max(getattr(least, f), getattr(work, f) * 3 // 4) for f in fields})
    return work


def _fit_preparing(work: _Work, least: _Work, frames: SplitCounts, costs: UnitCosts, network: str,
                   recipe: FinetuneRecipe, allowed: float) -> _Work:
    """Fewer augmented copies (the rehearsal following the rendered share), then fewer rehearsal frames, until
    preparing fits."""
    def preparing(candidate: _Work) -> float:
        seconds = _seconds(candidate, frames, costs, network, recipe)
        return seconds["augment"] + seconds["rehearsal"]

    while preparing(work) > allowed and work.copies > least.copies:
        copies = work.copies - 1
        work = replace(work, copies=copies, rehearsal=recipe.rehearsal_frames(frames.train * (1 + copies)))
    while preparing(work) > allowed and work.rehearsal > least.rehearsal:
        work = replace(work, rehearsal=max(least.rehearsal, work.rehearsal * 3 // 4))
    return work


def _cuts(wanted: _Work, work: _Work, frames: SplitCounts, recipe: FinetuneRecipe) -> tuple[str, ...]:
    """What the plan does less of than the recipe asks, each in words."""
    minutes = f"the {recipe.minutes:g} minutes on this machine"
    cuts = []
    if work.copies < wanted.copies:
        cuts.append(f"{work.copies} augmented copies of each of your {frames.train:,} training frames, not "
                    f"{wanted.copies}: more would not fit {minutes}")
    rendered_share = recipe.rehearsal_frames(frames.train * (1 + work.copies))
    if work.rehearsal < rendered_share:
        cuts.append(f"{work.rehearsal:,} rehearsal frames, not the {rendered_share:,} a rendered share of "
                    f"{recipe.rendered_share:g} asks for: more would not fit {minutes}")
    if work.evaluation < wanted.evaluation:
        cuts.append(f"each rendered set judged on {work.evaluation} frames, not {wanted.evaluation}")
    if work.held_out < wanted.held_out:
        cuts.append(f"the models judged on {work.held_out} of your {wanted.held_out} held-out frames")
    if work.blend < wanted.blend:
        cuts.append(f"the training validated and each blend scored on {work.blend} of your {wanted.blend} valid "
                    "frames")
    return tuple(cuts)


def _seconds(work: _Work, frames: SplitCounts, costs: UnitCosts, network: str,
             recipe: FinetuneRecipe) -> dict[str, float]:
    """Each stage's estimated seconds but training's own, for ``work`` on an export of ``frames``."""
    total = frames.train + frames.valid + frames.test
    parallel = max(costs.workers, 1)
    trained = frames.train * (1 + work.copies) + work.rehearsal
    if network == "crops":
        training_start = TRAINING_START_S[network] + CROP_PASS * costs.decode * (trained + work.blend)
    else:  # Ultralytics validates on the valid frames the blend is scored on after the last epoch
        training_start = TRAINING_START_S[network] + work.blend * costs.judge + 0.002 * trained
    judged = JUDGED_MODELS * (work.held_out + RENDERED_SETS * work.evaluation)
    return {"start": FIXED_S,
            "dataset": 2 * total * costs.decode,
            "paint": (frames.train + frames.valid) * costs.decode,
            "augment": (frames.train * work.copies * costs.augment) / parallel + total * costs.decode,
            "rehearsal": work.rehearsal * costs.render / parallel,
            "training start": training_start,
            "blend": len(BLEND_SHARES) * work.blend * costs.judge,
            "export": EXPORT_S[network],
            "evaluate": RENDERED_SETS * work.evaluation * costs.render / parallel + judged * costs.judge}


def describe(plan: JobPlan) -> str:
    """The plan in one line for the terminal."""
    share = ", ".join(f"{name} {seconds / 60:.1f}" for name, seconds in plan.seconds.items() if seconds >= 6)
    return (f"{plan.minutes:g} minutes planned on this machine ({share}; {MARGIN:.0%} kept in hand): "
            f"{plan.copies} augmented copies, {plan.rehearsal_frames:,} rehearsal frames, "
            f"{plan.evaluation_frames} frames per judging set")
