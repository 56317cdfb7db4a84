"""How much work ``poles demo`` does: the budgets it offers and how the fast one fits its training into the whole
run's time."""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

from augment.config import THESIS_COPIES

#: What the stages around training took on this project's two-core test machine (Intel Xeon) in the fast budget:
#: before it (data, check, augment) and after it (export, calibration, evaluation, SLAM, timing the front ends, and
#: training's own setup and final validation beyond its time cap). A machine that took longer before training is
#: taken to be as much slower after it.
BEFORE_TRAINING_S = 34.0
AFTER_TRAINING_S = 200.0
#: Training gets at least this long, however slow the machine.
MIN_TRAINING_S = 120.0
#: The share of the stages after training that come after the export (calibrate, evaluate, slam, speed), and the
#: share of those that scales with the calibration shots and the SLAM walk, measured on a fast demo (`poles demo`,
#: stages.json, two-core EPYC: training 33 s past its cap and export 34 s, then calibrate 23, evaluate 51, slam 130
#: and speed 21 s: 225 of 292 s, of which 153 scale).
AFTER_EXPORT_SHARE, SCALABLE_SHARE = 0.77, 0.68
#: A demo re-planned after a late training keeps at least these: calibration shots, seconds of walk, seeds compared.
MIN_CALIBRATION_SHOTS, MIN_WALK_S, MIN_COMPARE_SEEDS = 30, 30.0, 1
#: A shortfall under this share of the plan is noise in the timings, not a reason to cut.
REPLAN_TOLERANCE = 0.1


@dataclass(frozen=True)
class Budget:
    """How much work each stage does. ``train_hours`` caps training time (Ultralytics fits the epochs to it);
    ``whole_minutes``, when given, is the whole run's time: training gets what the other stages leave of it.
    ``conf`` None picks the confidence threshold that maximises F1 on the validation split (or, when that split
    holds too few poles to choose on, keeps the threshold the starting model shipped with)."""

    name: str
    images: int
    copies: int
    models: tuple[str, ...]
    imgsz: int
    epochs: int
    train_hours: float | None
    batch: int
    export_hw: tuple[int, int]
    calibration_shots: int
    walk_seconds: float
    compare_seeds: int
    conf: float | None
    rationale: str = ""
    whole_minutes: float | None = None

    def smallest_minutes(self) -> float:
        """The least whole-run time that leaves training ``MIN_TRAINING_S`` on the test machine (to half a minute)."""
        return math.ceil(2 * (BEFORE_TRAINING_S + AFTER_TRAINING_S + MIN_TRAINING_S) / 60) / 2

    def with_minutes(self, minutes: float) -> "Budget":
        """This budget with the whole run's time set to ``minutes``; refused, naming the least that works, when that
        is less than ``smallest_minutes``, or when the budget trains for its epochs rather than a time."""
        if self.whole_minutes is None:
            raise ValueError(f"--minutes sets the whole run's time of a budget that trains for a time: the {self.name} "
                             f"budget trains for its {self.epochs} epochs - leave out --minutes or use --budget fast")
        if minutes < self.smallest_minutes():
            raise ValueError(f"--minutes {minutes:g} is less than the demo needs: at least {self.smallest_minutes():g} "
                             "minutes (its stages around training, and two minutes of training, on a two-core "
                             f"machine) - give --minutes {self.smallest_minutes():g} or more")
        return replace(self, whole_minutes=minutes)

    def training_hours(self, spent_s: float) -> float | None:
        """The training's time cap after ``spent_s`` seconds of the stages before it: ``train_hours``, shortened so
        that the whole run stays within ``whole_minutes`` on a machine as much slower than the test machine after
        training as it was before (at least ``MIN_TRAINING_S``)."""
        if self.whole_minutes is None:
            return self.train_hours
        left_s = max(MIN_TRAINING_S, 60 * self.whole_minutes - spent_s - self.after_training_s(spent_s))
        return min(left_s / 3600, self.train_hours) if self.train_hours else left_s / 3600

    @staticmethod
    def after_training_s(before_s: float) -> float:
        """What the stages after training are planned to take on a machine that took ``before_s`` for the stages
        before it: ``AFTER_TRAINING_S``, slowed as much as those were (never sped up)."""
        return max(1.0, before_s / BEFORE_TRAINING_S) * AFTER_TRAINING_S

    def after_export(self, spent_s: float, before_s: float) -> tuple["Budget", str | None]:
        """The stages after the export fitted again to what is left of ``whole_minutes`` once ``spent_s`` are spent
        (training runs past its cap on a busy machine, and a slow one trains ``MIN_TRAINING_S`` whatever is left),
        on a machine that took ``before_s`` for the stages before training: when less is left than they are planned
        to take, fewer calibration shots, a shorter SLAM walk and fewer seeds compared (each at least its ``MIN_``),
        with a line saying so; else this budget and None."""
        left_s = 60 * self.whole_minutes - spent_s if self.whole_minutes is not None else math.inf
        planned_s = AFTER_EXPORT_SHARE * self.after_training_s(before_s)
        if left_s >= (1 - REPLAN_TOLERANCE) * planned_s:
            return self, None
        fixed_s = (1 - SCALABLE_SHARE) * planned_s
        scale = max(0.0, (left_s - fixed_s) / (planned_s - fixed_s))
        cut = replace(self, calibration_shots=max(MIN_CALIBRATION_SHOTS, round(self.calibration_shots * scale)),
                      walk_seconds=max(MIN_WALK_S, round(self.walk_seconds * scale)),
                      compare_seeds=max(MIN_COMPARE_SEEDS, round(self.compare_seeds * scale)))
        return cut, (f"{spent_s / 60:.1f} of {self.whole_minutes:g} minutes spent after training and export, and the "
                     f"stages after them need about {planned_s / 60:.1f} here: {cut.calibration_shots} calibration "
                     f"shots (not {self.calibration_shots}), a {cut.walk_seconds:g} s walk (not "
                     f"{self.walk_seconds:g}) and {cut.compare_seeds} seed(s) compared (not {self.compare_seeds})")


BUDGETS = {
    "fast": Budget("fast", images=300, copies=THESIS_COPIES, models=("yolov8n-seg",), imgsz=640, epochs=100,
                   train_hours=0.17, whole_minutes=12.0, batch=8, export_hw=(480, 640), calibration_shots=90,
                   walk_seconds=90.0, compare_seeds=3, conf=None, rationale=(
                       "About 13 minutes on two cores, 10 of them training. The run fine-tunes the shipped "
                       "pole-pretrained YOLOv8n (its line trained on 68,000 rendered frames, most over real "
                       "robot-camera backgrounds) on this dataset at 640 px, the Nao's full frame width, so that far "
                       "poles are learnt at the pixel size they have on the robot; ten minutes start from a good model "
                       "instead of from nothing, and the evaluation compares the result with the shipped model as "
                       "installed (on rendered frames like its own training data they seldom improve it). Exported "
                       "at 640x480; the shipped model's threshold is kept, since 30 validation frames are too few to "
                       "choose one on. "
                       "YOLOv8s/m from scratch need hours to days here (--budget full).")),
    # The thesis's settings: YOLOv8s and YOLOv8m at 640 px for 200 epochs (days on a laptop CPU).
    "full": Budget("full", images=1000, copies=THESIS_COPIES, models=("yolov8s-seg", "yolov8m-seg"), imgsz=640,
                   epochs=200, train_hours=None, batch=8, export_hw=(480, 640), calibration_shots=270,
                   walk_seconds=90.0, compare_seeds=10, conf=0.85, rationale=(
                       "The 2024 thesis's settings: YOLOv8s and YOLOv8m at 640 px for 200 epochs, detections used "
                       "from confidence 0.85. On a two-core CPU this takes days.")),
}
