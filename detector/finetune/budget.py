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
from detector.stages import late_note

#: The share of the minutes the plan keeps in hand for what it cannot foresee (a busy machine, a slow disk).
MARGIN = 0.08
#: At most these shares of the minutes go to preparing (augmenting, rendering the rehearsal) and to judging
#: (choosing the blend, judging the models); training gets the rest.
PREPARING_SHARE, JUDGING_SHARE = 0.3, 0.25
#: At most this share of the minutes goes to the teacher labelling unlabelled frames (``--unlabelled``), before the
#: plan fits the rest to what is left.
TEACHING_SHARE = 0.25
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
#: Seconds one training frame of the accurate model costs (Ultralytics' loader, forward and backward) per second
#: judging one frame costs, both at the training size: 0.45 s against 0.16 s measured on a two-core EPYC.
TRAINING_PER_JUDGED_FRAME = 3.0
#: Seconds one epoch of the robot's crop network costs per training frame (the crops cut from it), per second the
#: robot front end takes to judge a frame: 5.3-5.5 ms against 7.0-7.5, and 2.8-3.7 against 4.1-4.3, in five
#: fine-tunes on two two-core EPYCs (0.69-0.90); the largest is kept, so the plan never promises time it lacks.
CROP_EPOCH_PER_JUDGED_FRAME = 0.9
#: The largest slowdown of the stages after training that the stages before it can be taken to show.
MAX_LOAD = 10.0
#: Each stage as ``stages.json`` names it, and the parts of the plan that estimate it.
PLANNED_PARTS = {"dataset": ("start", "dataset"), "train": ("training start", "train")}


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
    #: The accurate model's estimated seconds for one pass over its training frames, and the least minutes whose
    #: plan trains a whole pass, with the recipe's copies and with none (None for the crop network, which trains
    #: many epochs a minute, and when the training's share already buys a pass).
    epoch_seconds: float | None = None
    one_epoch_minutes: float | None = None
    one_epoch_minutes_without_copies: float | None = None

    def after_training_seconds(self) -> float:
        """What the stages after training are expected to take."""
        return sum(self.seconds[name] for name in ("blend", "export", "evaluate"))

    def short_of_an_epoch(self) -> str | None:
        """A warning, in words, when the training's share buys less than one pass over its frames; else None."""
        if self.epoch_seconds is None or self.seconds["train"] >= self.epoch_seconds:
            return None
        share = self.seconds["train"] / self.epoch_seconds
        fewer = self.one_epoch_minutes_without_copies
        cheaper = fewer is not None and fewer < self.one_epoch_minutes
        without = f", --minutes {fewer:g} with --copies 0" if cheaper else ""
        return (f"the training gets {self.seconds['train'] / 60:.1f} minutes, about {share:.0%} of one pass over its "
                f"frames (one pass takes about {self.epoch_seconds / 60:.1f} minutes here): it will learn little - "
                f"--minutes {self.one_epoch_minutes:g} buys a whole pass on this machine with the augmented copies "
                f"that budget plans{without}")

    def planned(self, stage: str) -> float:
        """The seconds this plan gives ``stage`` (a name in ``stages.json``)."""
        return sum(self.seconds.get(part, 0.0) for part in PLANNED_PARTS.get(stage, (stage,)))


def training_minutes(plan: JobPlan, spent_minutes: float) -> float:
    """The training's time cap once ``spent_minutes`` are spent: the minutes (less the margin) left after what the
    training's start and the stages after it are expected to take; at least the least training."""
    later = (plan.seconds["training start"] + plan.after_training_seconds()) / 60
    return max(MIN_TRAINING_S[plan.network] / 60, plan.minutes * (1 - MARGIN) - spent_minutes - later)


def measure_costs(samples: list[Sample], render: Callable[[], object], judge: Callable[[np.ndarray], object],
                  augment: Callable[[Sample], object], workers: int) -> UnitCosts:
    """Time each unit of work once or twice on the export's own frames: decoding, augmenting one copy, rendering
    one rehearsal frame and judging one frame with the starting model (each after one untimed call: the first
    loads the model, the renderer's backdrops and scene, and took twice a rendered frame's steady cost)."""
    images = [sample.image for sample in samples if sample.image is not None][:3]
    began = time.perf_counter()
    frames = [cv2.imread(str(image)) for image in images]
    decode = (time.perf_counter() - began) / max(len(images), 1)
    labelled = next((sample for sample in samples if sample.instances), samples[0])
    augment_s = _timed(lambda: augment(labelled))
    render()
    render_s = _timed(render)
    return UnitCosts(decode, augment_s, render_s, judging_seconds(judge, frames) + decode, workers)


def judging_seconds(judge: Callable[[np.ndarray], object], frames: list[np.ndarray]) -> float:
    """Seconds ``judge`` takes a frame: one untimed call that loads it, then the mean over up to three frames (a
    model that finds many weak poles is slow on every frame, not on the fastest)."""
    judge(frames[0])
    timed = frames[1:4] or frames[:1]
    return sum(_timed(lambda: judge(frame)) for frame in timed) / len(timed)


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


def plan_job(recipe: FinetuneRecipe, frames: SplitCounts, costs: UnitCosts, network: str,
             taught_s: float = 0.0) -> JobPlan:
    """Fit the fine-tune of an export with ``frames`` (after the valid split is made) into ``recipe.minutes``, less
    the ``taught_s`` the teacher already took labelling unlabelled frames (kept in the plan as ``teacher``):
    judging first cut to ``JUDGING_SHARE`` of them, then preparing to ``PREPARING_SHARE``, training the rest.
    ``BudgetTooSmall`` names the least minutes that work here when even the least work does not fit."""
    budget = 60 * recipe.minutes * (1 - MARGIN) - taught_s
    held_out_all = frames.test or frames.valid
    wanted = _wanted(recipe, frames)
    least = _Work(0, min(MIN_REHEARSAL_FRAMES, recipe.rehearsal_frames(frames.train)),
                  min(MIN_EVALUATION_FRAMES, recipe.evaluation_frames), min(MIN_TEAM_FRAMES, held_out_all),
                  min(MIN_TEAM_FRAMES, frames.valid))
    needed = sum(_seconds(least, frames, costs, network, recipe).values()) + MIN_TRAINING_S[network]
    if needed > budget:
        smallest = math.ceil(2 * (needed + taught_s) / 60 / (1 - MARGIN)) / 2
        raise BudgetTooSmall(f"--minutes {recipe.minutes:g} is less than this fine-tune needs on this machine: "
                             f"at least {smallest:g} minutes for {frames.train + frames.valid + frames.test:,} frames "
                             f"(the least checking, rendering, training and judging take {needed / 60:.1f}) - give "
                             f"--minutes {smallest:g} or more")
    work, seconds = _fitted(wanted, least, frames, costs, network, recipe, budget)
    if taught_s:
        seconds = {"teacher": round(taught_s, 1), **seconds}
    epoch = _epoch_seconds(work, frames, costs) if network == "yolo" else None
    one_epoch = without_copies = None
    if epoch is not None and seconds["train"] < epoch:
        one_epoch = _minutes_for_one_epoch(wanted, least, frames, costs, recipe)
        no_copies = replace(recipe, copies=0)
        without_copies = _minutes_for_one_epoch(
            replace(wanted, copies=0, rehearsal=no_copies.rehearsal_frames(frames.train)), least, frames, costs,
            no_copies)
    return JobPlan(recipe.minutes, network, costs, work.copies, work.rehearsal, work.evaluation,
                   None if work.held_out >= held_out_all else work.held_out,
                   None if work.blend >= frames.valid else work.blend, seconds, _cuts(wanted, work, frames, recipe),
                   epoch, one_epoch, without_copies)


def _wanted(recipe: FinetuneRecipe, frames: SplitCounts) -> _Work:
    """The work the recipe asks for on these frames, before anything is cut to fit the minutes."""
    return _Work(recipe.copies, recipe.rehearsal_frames(frames.train * (1 + recipe.copies)),
                 recipe.evaluation_frames, frames.test or frames.valid, frames.valid)


def _fitted(wanted: _Work, least: _Work, frames: SplitCounts, costs: UnitCosts, network: str,
            recipe: FinetuneRecipe, budget: float) -> tuple[_Work, dict[str, float]]:
    """The work fitted to ``budget`` seconds and each stage's seconds, ``train`` the seconds left for training."""
    work = _fit_judging(wanted, least, frames, costs, network, recipe, JUDGING_SHARE * budget)
    work = _fit_preparing(work, least, frames, costs, network, recipe, PREPARING_SHARE * budget)
    if network == "crops" and recipe.epoch_cap is not None:
        work = _rehearsal_the_epochs_leave(work, wanted, frames, costs, recipe, budget)
    seconds = _seconds(work, frames, costs, network, recipe)
    if budget - sum(seconds.values()) < MIN_TRAINING_S[network]:  # the shares left too little: the least instead
        work = least
        seconds = _seconds(work, frames, costs, network, recipe)
    seconds["train"] = round(budget - sum(seconds.values()), 1)
    return work, seconds


def _rehearsal_the_epochs_leave(work: _Work, wanted: _Work, frames: SplitCounts, costs: UnitCosts,
                                recipe: FinetuneRecipe, budget: float) -> _Work:
    """The crop network stops at its epoch cap, often well within the training's share: the most rehearsal frames
    (up to the recipe's rendered share) whose rendering and capped training still fit ``budget``, so minutes the
    epochs would leave unused go to the rehearsal the preparing share had cut."""
    def fits(rehearsal: int) -> bool:
        candidate = replace(work, rehearsal=rehearsal)
        return (sum(_seconds(candidate, frames, costs, "crops", recipe).values())
                + _crop_training_seconds(candidate, frames, costs, recipe.epoch_cap) <= budget)

    low, high = work.rehearsal, wanted.rehearsal
    if high <= low or not fits(low):
        return work
    while high - low > 1:
        middle = (low + high) // 2
        low, high = (middle, high) if fits(middle) else (low, middle)
    return replace(work, rehearsal=high if fits(high) else low)


def _crop_training_seconds(work: _Work, frames: SplitCounts, costs: UnitCosts, epochs: int) -> float:
    """The crop network's estimated seconds for ``epochs`` passes over ``work``'s training frames."""
    return epochs * _trained_frames(work, frames) * CROP_EPOCH_PER_JUDGED_FRAME * costs.judge


def _epoch_seconds(work: _Work, frames: SplitCounts, costs: UnitCosts) -> float:
    """The accurate model's estimated seconds for one pass over ``work``'s training frames."""
    return round(_trained_frames(work, frames) * TRAINING_PER_JUDGED_FRAME * costs.judge, 1)


def _trained_frames(work: _Work, frames: SplitCounts) -> int:
    """The frames one training pass of ``work`` goes over: the team's train frames, their augmented copies and the
    rehearsal."""
    return frames.train * (1 + work.copies) + work.rehearsal


def _minutes_for_one_epoch(wanted: _Work, least: _Work, frames: SplitCounts, costs: UnitCosts,
                           recipe: FinetuneRecipe) -> float:
    """The least ``--minutes`` (in half minutes) whose plan trains the accurate model for one whole pass."""
    def enough(half_minutes: int) -> bool:
        work, seconds = _fitted(wanted, least, frames, costs, "yolo", recipe, 60 * half_minutes / 2 * (1 - MARGIN))
        return seconds["train"] >= _epoch_seconds(work, frames, costs)

    low, high = math.ceil(2 * recipe.minutes), math.ceil(2 * recipe.minutes) + 1
    while not enough(high):
        low, high = high, 2 * high
    while high - low > 1:
        middle = (low + high) // 2
        low, high = (low, middle) if enough(middle) else (middle, high)
    return high / 2


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


def _cuts(wanted: _Work, work: _Work, frames: SplitCounts, recipe: FinetuneRecipe,
          after_training: bool = False) -> tuple[str, ...]:
    """What the plan does less of than the recipe asks, each in words (``after_training``: the re-plan's, which
    cannot change the frames the training validated on)."""
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
        scored = "each blend scored" if after_training else "the training validated and each blend scored"
        cuts.append(f"{scored} on {work.blend} of your {wanted.blend} valid frames")
    return tuple(cuts)


def _seconds(work: _Work, frames: SplitCounts, costs: UnitCosts, network: str,
             recipe: FinetuneRecipe) -> dict[str, float]:
    """Each stage's estimated seconds but training's own, for ``work`` on an export of ``frames``."""
    total = frames.train + frames.valid + frames.test
    parallel = max(costs.workers, 1)
    trained = _trained_frames(work, frames)
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


def machine_load(plan: JobPlan, taken: dict[str, float]) -> float:
    """How much slower than planned this machine ran the stages before training whose work was timed at the start
    (painting, augmenting, rendering): 1 where they kept to the plan or took too little to tell, at most
    ``MAX_LOAD``."""
    names = ("paint", "augment", "rehearsal")
    planned = sum(plan.seconds[name] for name in names)
    if planned < 5.0:
        return 1.0
    return min(MAX_LOAD, max(1.0, sum(taken.get(name, 0.0) for name in names) / planned))


def replan_after_training(plan: JobPlan, recipe: FinetuneRecipe, frames: SplitCounts, spent_s: float,
                          judge_s: float, load: float) -> JobPlan:
    """The stages after training fitted again to what is left of the minutes once ``spent_s`` are spent: judging
    timed with the fine-tuned model (``judge_s`` a frame; a fine-tune that finds many weak poles judges slower than
    the model it started from), rendering and exporting slowed by ``load``, the margin kept in hand for them alone.
    The judged frames are cut, a quarter at a time down to their least, until blend, export and evaluate fit; never
    raised above the first plan's."""
    costs = replace(plan.costs, render=plan.costs.render * load, judge=max(judge_s, plan.costs.judge * load))
    held_out_all = frames.test or frames.valid
    wanted = _wanted(recipe, frames)
    work = _Work(plan.copies, plan.rehearsal_frames, plan.evaluation_frames, plan.held_out_frames or held_out_all,
                 plan.blend_frames or frames.valid)
    least = replace(work, evaluation=min(MIN_EVALUATION_FRAMES, work.evaluation),
                    held_out=min(MIN_TEAM_FRAMES, work.held_out), blend=min(MIN_TEAM_FRAMES, work.blend))
    export_s = EXPORT_S[plan.network] * load
    left = 60 * plan.minutes - spent_s - export_s - MARGIN * plan.after_training_seconds()
    work = _fit_judging(work, least, frames, costs, plan.network, recipe, left)
    seconds = _seconds(work, frames, costs, plan.network, recipe)
    return replace(plan, costs=costs, evaluation_frames=work.evaluation,
                   held_out_frames=None if work.held_out >= held_out_all else work.held_out,
                   blend_frames=None if work.blend >= frames.valid else work.blend,
                   seconds={**plan.seconds, "blend": seconds["blend"], "export": export_s,
                            "evaluate": seconds["evaluate"]},
                   cuts=_cuts(wanted, work, frames, recipe, after_training=True))


def overrun_note(plan: JobPlan, taken: dict[str, float], between_s: float) -> str | None:
    """When the stages (``taken``) and the time between them (``between_s``: reports, loading) took longer in all
    than the minutes: by how much, and the stages that ran furthest past their plan; None when the job kept to its
    minutes."""
    return late_note("this fine-tune", plan.minutes, sum(taken.values()) + between_s,
                     [(name, seconds, plan.planned(name)) for name, seconds in taken.items()])


def describe(plan: JobPlan) -> str:
    """The plan in one line for the terminal."""
    share = ", ".join(f"{name} {seconds / 60:.1f}" for name, seconds in plan.seconds.items() if seconds >= 6)
    return (f"{plan.minutes:g} minutes planned on this machine ({share}; {MARGIN:.0%} kept in hand): "
            f"{plan.copies} augmented copies, {plan.rehearsal_frames:,} rehearsal frames, "
            f"{plan.evaluation_frames} frames per judging set")
