"""What each stage of ``poles demo`` hands on, and the whole run's result."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from augment.run import AugmentSummary
from calibration.run import CalibrationResult
from detector.datasets.io import SplitCounts
from detector.evaluation.paired import F1Difference
from detector.evaluation.results import Evaluation
from detector.records import JsonRecord
from detector.slam.comparison import BackendRow
from detector.slam.figures import RunFigures
from detector.training.summary import TrainingSummary
from export.run import ExportReport


@dataclass(frozen=True)
class DatasetSummary(JsonRecord):
    """The rendered dataset: frames in all and per split, labelled poles, frames without one, and its preview."""

    images: int
    frames: SplitCounts
    poles: int
    empty: int
    preview: Path


@dataclass(frozen=True)
class CheckSummary(JsonRecord):
    """What ``poles check`` found in the rendered dataset (a run with errors stops there)."""

    errors: int
    warnings: int


@dataclass(frozen=True)
class EvaluatedFrontEnd(JsonRecord):
    """One front end's evaluation and the folder of its plots and overlays."""

    evaluation: Evaluation
    folder: Path


@dataclass(frozen=True)
class AgainstShipped(JsonRecord):
    """What the training bought: the trained model's F1 less the shipped model's (at its own threshold) on the same
    test frames."""

    model: str
    reference: str
    reference_conf: float
    change: F1Difference


@dataclass(frozen=True)
class DemoEvaluation(JsonRecord):
    """Every front end on the test frames at one threshold, and where that threshold came from."""

    front_ends: tuple[EvaluatedFrontEnd, ...]
    conf: float
    conf_source: str
    against_shipped: AgainstShipped


@dataclass(frozen=True)
class SlamRun(JsonRecord):
    """The walk through one front end into the chosen back end: its figures, sightings and plots."""

    front_end: str
    figures: RunFigures
    measurements: int
    map: Path
    errors: Path


@dataclass(frozen=True)
class DemoSlam(JsonRecord):
    """The walk through each front end, and the back ends compared (tables by title)."""

    backend: str
    walk_seconds: float
    runs: tuple[SlamRun, ...]
    tables: dict[str, tuple[BackendRow, ...]]


@dataclass(frozen=True)
class SpeedRow(JsonRecord):
    """One front end's median time per frame, one thread, capped at the Atom's instruction set and not (None where
    it was not timed, ``note`` saying why)."""

    front_end: str
    model: str
    capped_ms: float | None
    uncapped_ms: float | None
    note: str = ""


@dataclass(frozen=True)
class DemoSpeed(JsonRecord):
    """Both front ends timed on held-out frames with their camera poses, in fresh processes, with the engine used."""

    frames: int
    engine: str
    rows: tuple[SpeedRow, ...]


@dataclass(frozen=True)
class DemoResult:
    """Every stage's result, in the order they ran; the report is written from it."""

    data: DatasetSummary
    check: CheckSummary
    augment: AugmentSummary
    trainings: tuple[TrainingSummary, ...]
    exports: tuple[ExportReport, ...]
    calibrate: CalibrationResult
    evaluate: DemoEvaluation
    slam: DemoSlam
    speed: DemoSpeed
