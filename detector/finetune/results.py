"""What each stage of ``poles finetune`` hands on, and the whole run's result (``metrics.json`` in the run folder)."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from augment.run import AugmentSummary
from detector.datasets.io import SplitCounts
from detector.finetune.blend import BlendChoice
from detector.finetune.budget import JobPlan
from detector.finetune.intake import DatasetIntake
from detector.finetune.judge import Judgement
from detector.finetune.recipe import FinetuneRecipe
from detector.finetune.teacher import TeacherLabels
from detector.records import JsonRecord
from detector.synth.team_paint import TeamPaint
from detector.training.summary import TrainingSummary
from export.run import ExportReport


@dataclass(frozen=True)
class RehearsalSummary(JsonRecord):
    """The rendered frames mixed into training: how many, over how many backdrops, and their contact sheet."""

    frames: int
    backdrops: int = 0
    preview: Path | None = None


@dataclass(frozen=True)
class ExportedModel(JsonRecord):
    """The fine-tuned model's files and what they carry."""

    fp32: Path
    int8: Path | None
    #: Whether the starting model's range calibration rides along (it holds at the input width it was measured at).
    calibrated: bool
    #: The accurate model's export check against PyTorch (``poles export``'s report).
    check: ExportReport | None = None
    #: The crop network's largest output difference between ONNX and PyTorch.
    onnx_difference: float | None = None


@dataclass(frozen=True)
class FinetuneStages(JsonRecord):
    """Every stage's result, in the order they run (``teacher`` None without ``--unlabelled``)."""

    teacher: TeacherLabels | None
    dataset: DatasetIntake
    plan: JobPlan
    paint: TeamPaint
    augment: AugmentSummary
    rehearsal: RehearsalSummary
    mix: SplitCounts
    train: TrainingSummary
    #: The plan for the stages after training, fitted again once it had ended.
    replan: JobPlan
    blend: BlendChoice
    export: ExportedModel
    evaluate: Judgement


@dataclass(frozen=True)
class FinetuneResult(JsonRecord):
    """A fine-tune's recipe, every stage's result, the time each took and where the report is."""

    recipe: FinetuneRecipe
    stages: FinetuneStages
    #: Seconds per stage, as the ledger recorded them (a skipped stage keeps the time it took when it ran).
    seconds: dict[str, float]
    wall_seconds_this_call: float
    report: Path
