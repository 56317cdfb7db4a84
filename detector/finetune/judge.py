"""How a fine-tune is judged: the shipped model and the newcomers on the same frames (the team's held-out frames,
fresh rendered sets), counted as ``poles evaluate`` counts, each newcomer's F1 against the shipped model's with its
95 % interval over frames, and the recall of poles under 16 px wide (the first thing a small export forgets)."""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

from detector.formats import write_record
from detector.evaluation.paired import REFERENCE, F1Difference, f1_difference
from detector.evaluation.predictors import Predictor
from detector.evaluation.results import Counts
from detector.evaluation.run import evaluate
from detector.records import JsonRecord
from detector.synth.generate import SynthJob, generate_dataset
from detector.synth.scene import SceneConfig

#: Width bins (``evaluation.by_width``) that make up "under 16 px".
SMALL_BINS = ("< 10 px", "10-16 px")
#: The fresh rendered sets, by name, as (far share, seed), that every fine-tune is judged on besides the team's
#: held-out frames: what the shipped model was made for (varied paint, near and far) and far poles alone (3-9 m,
#: 6-18 px wide). Each has its own seed and is never trained on.
RENDERED_SETS = {"rendered": (0.0, 9101), "far poles": (1.0, 9102)}


@dataclass(frozen=True)
class JudgeRow(JsonRecord):
    """One model on one set of frames, counted as ``poles evaluate`` counts, with its evaluation folder."""

    set_name: str
    model: str
    images: int
    counts: Counts
    precision: float
    recall: float
    f1: float
    #: Labelled poles under 16 px wide, and how many of them were found.
    small_labels: int
    small_found: int
    folder: Path
    #: F1 against the shipped model (``REFERENCE``) on the same frames; None for the shipped model itself.
    f1_change: F1Difference | None = None

    @property
    def recall_under_16px(self) -> float | None:
        return self.small_found / self.small_labels if self.small_labels else None


@dataclass(frozen=True)
class Judgement(JsonRecord):
    """Every model on every set at one threshold; ``held_out`` names the team's split that was judged on."""

    held_out: str
    conf: float
    rows: tuple[JudgeRow, ...]


def render_set(folder: Path, frames: int, far_share: float, seed: int, backgrounds: tuple[Path, ...] = (),
               backlight_share: float | None = None) -> Path:
    """A fresh 640x480 set, every frame in its test split (over ``backgrounds`` when given)."""
    config = SceneConfig(far_share=far_share) if backlight_share is None else \
        SceneConfig(far_share=far_share, backlight_share=backlight_share)
    return generate_dataset(folder, SynthJob(frames, seed, config=config, backgrounds=backgrounds), force=True,
                            split="test")


def compare_models(models: dict[str, Path], sets: dict[str, tuple[Path, str, int | None]], folder: Path, conf: float,
                   predictor_of: Callable[[Path], Predictor]) -> list[JudgeRow]:
    """Every model (checkpoints by name, the shipped one as ``REFERENCE`` among them, each run by ``predictor_of``) on
    every set (dataset, split, the first so many frames of it or None for all; each checked before) at ``conf``; one
    row per set and model, written to ``folder``/summary.json with each model's evaluation folder."""
    rows = []
    for set_name, (dataset, split, frames) in sets.items():
        per_image, set_rows = {}, []
        for model_name, weights in models.items():
            out = Path(folder) / set_name.replace(" ", "-") / model_name.replace(" ", "-")
            metrics = evaluate(predictor_of(weights), dataset, out, split, conf, frames=frames, check=False)
            per_image[model_name] = metrics.per_image
            small = [row for row in metrics.recall_by_width if row.width in SMALL_BINS]
            set_rows.append(JudgeRow(set_name, model_name, metrics.images, metrics.counts, metrics.precision,
                                     metrics.recall, metrics.f1, sum(row.labels for row in small),
                                     sum(row.found for row in small), out))
        rows += [row if row.model == REFERENCE else
                 replace(row, f1_change=f1_difference(per_image[REFERENCE], per_image[row.model]))
                 for row in set_rows]
    write_record(Path(folder) / "summary.json", "judgement", [row.to_json() for row in rows])
    return rows
