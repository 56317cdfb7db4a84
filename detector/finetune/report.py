"""report.html of a fine-tune: what it gained on the team's own held-out frames and what it lost on rendered frames
unlike them, beside the stages, the paint, the training curves and the blend that was chosen."""
from __future__ import annotations

import html
from pathlib import Path

from detector.atomic import write_text
from detector.finetune.blend import BlendChoice
from detector.finetune.budget import JobPlan, describe
from detector.finetune.judge import Judgement
from detector.finetune.results import ExportedModel, FinetuneResult, FinetuneStages
from detector.finetune.teacher import TEST_EVERY
from detector.html_page import image, page, percent, table
from detector.stages import StageRecord
from detector.training.summary import TrainingSummary
from export.run import verdict


def write_report(result: FinetuneResult, timings: list[StageRecord]) -> Path:
    """Write the report of a fine-tune to ``result.report``."""
    stages = result.stages
    parts = [f"<h1>poles finetune: {html.escape(str(stages.dataset.source))}</h1>",
             f"<p class='note'>The shipped {html.escape(result.recipe.model)} model, fine-tuned on your frames.</p>",
             _verdict(stages.evaluate), _evaluation(stages.evaluate),
             _stages(timings, result.recipe.settings(), stages.replan),
             _data(stages), _training(stages.train), _blend(stages.blend), _export(stages.export)]
    return write_text(result.report, page("poles finetune report", parts))


def changes(judgement: Judgement) -> list[str]:
    """One line per rendered or held-out set: the chosen model's F1 change against the shipped model, 95 % interval."""
    lines = []
    for row in judgement.rows:
        if row.model.startswith("blend") and row.f1_change is not None:
            change = row.f1_change
            lines.append(f"{row.set_name}: F1 {100 * change.difference:+.1f} points (95 % {100 * change.low:+.1f} "
                         f"to {100 * change.high:+.1f}) against the shipped model")
    return lines


def _verdict(judgement: Judgement) -> str:
    items = "".join(f"<li>{html.escape(line)}</li>" for line in changes(judgement))
    return ("<h2>What the fine-tune changed</h2><p>The model that ships from this run (the blend) against the shipped "
            f"model, both at its threshold {judgement.conf:.2f}:</p><ul>{items}</ul>")


def _evaluation(judgement: Judgement) -> str:
    header = ["set", "model", "images", "TP", "FP", "FN", "TN", "precision", "recall", "F1",
              "F1 change (95 %)", "recall < 16 px"]
    rows = []
    for r in judgement.rows:
        change = r.f1_change
        rows.append([r.set_name, r.model, r.images, r.counts.tp, r.counts.fp, r.counts.fn, r.counts.tn,
                     percent(r.precision), percent(r.recall),
                     f"{r.f1:.3f}",
                     f"{100 * change.difference:+.1f} ({100 * change.low:+.1f} to {100 * change.high:+.1f})"
                     if change else "-",
                     f"{percent(r.recall_under_16px)} of {r.small_labels}" if r.small_labels else "-"])
    note = ("Counted per image as the thesis did: a detection is a true positive when its class matches and its mask "
            "overlaps the label with IoU &ge; 0.5. The F1 change is against the shipped model on the same frames, its "
            "interval drawn over frames. The rendered sets were rendered for this evaluation and never trained on"
            + (". There is no test split, so your frames are the valid split that also chose the blend: the figures "
               "on them flatter every fine-tuned model" if judgement.held_out == "valid" else "") + ".")
    folders = "".join(f"<h3>{html.escape(r.set_name)}: {html.escape(r.model)}</h3><div class='row'>"
                      + image(r.folder / "per_image.png", "per image")
                      + image(r.folder / "recall_by_width.png", "recall by pole width") + "</div>"
                      for r in judgement.rows if r.model != "fine-tune")
    return f"<h2>Evaluation</h2><p class='note'>{note}</p>" + table(header, rows) + folders


def _stages(timings: list[StageRecord], settings: dict, plan: JobPlan) -> str:
    rows = [[r.name, r.status + ("" if r.ran else " (reused)"), f"{r.seconds:.0f}", f"{plan.planned(r.name):.0f}"]
            for r in timings]
    recipe = [[key.replace("_", " "), value] for key, value in settings.items()]
    cuts = "".join(f"<li>{html.escape(cut)}</li>" for cut in plan.cuts)
    return ("<h2>Stages and time taken</h2>"
            f"<p>{html.escape(describe(plan))}.</p>" + (f"<p>Cut to fit:</p><ul>{cuts}</ul>" if cuts else "")
            + table(["stage", "status", "seconds", "planned"], rows)
            + f"<p>Total {sum(r.seconds for r in timings) / 60:.1f} min of the {plan.minutes:g} asked for.</p>"
            + table(["recipe", "value"], recipe))


def _swatch(rgb: tuple[float, float, float]) -> str:
    red, green, blue = (round(255 * c) for c in rgb)
    return (f"<span style='display:inline-block;width:2.5em;height:1.2em;vertical-align:middle;"
            f"background:rgb({red},{green},{blue})'></span>")


def _data(stages: FinetuneStages) -> str:
    intake, paint, mix = stages.dataset, stages.paint, stages.mix
    split_note = " (valid made from train: the export had none)" if intake.valid_made_from_train else ""
    swatches = "".join(f"<tr><td>{letter}</td><td>{_swatch(rgb)}</td><td>{paint.measured[letter]}</td></tr>"
                       for letter, rgb in paint.letters.items())
    frames = intake.frames
    taught = stages.teacher
    teacher = "" if taught is None else (
        f"<p>Unlabelled frames: {html.escape(str(taught.source))}, {taught.frames} read; the teacher "
        f"({html.escape(taught.teacher)}, sure at {taught.sure_conf:.2f}) labelled {taught.kept} ({taught.poles} "
        f"poles, {taught.pole_free} frames without one) and left {taught.unsure} out: where a detection lay between "
        f"{taught.floor_conf:.2f} and {taught.sure_conf:.2f}, or ({taught.disputed}) where the robot model named one "
        f"of its poles another landmark. Every {TEST_EVERY}th kept frame ({taught.test}) was "
        "held out: judged against the teacher's labels, those figures say how far the robot model agrees with its "
        "teacher, not with the truth.</p>")
    return (f"<h2>Your frames</h2>{teacher}<p>train {frames.train}, valid {frames.valid}{split_note}, test "
            f"{frames.test}; {intake.poles} poles. Training set: {mix.train} frames (your augmented frames and "
            f"{stages.rehearsal.frames} rendered in your paint), validated on {mix.valid}.</p>"
            f"<p>Paint measured on {paint.poles} poles ({paint.skipped} too small), "
            "white-balanced against each pole's base:</p>"
            f"<table><tr><th>band</th><th>paint</th><th>bands measured</th></tr>{swatches}</table>"
            "<div class='row'>" + image(stages.augment.preview or "", "augmented copies")
            + image(stages.rehearsal.preview or "", "rehearsal frames in your paint") + "</div>")


def _training(train: TrainingSummary) -> str:
    return (f"<h2>Training</h2><p>{train.minutes or 0:.1f} minutes from the shipped checkpoint, {train.epochs} epochs; "
            "the final weights are the fine-tune (a valid split of a few frames cannot choose an epoch).</p>"
            + image(train.curves, "training curves"))


def _blend(blend: BlendChoice) -> str:
    rows = [[f"{score.share:g}", score.counts.tp, score.counts.fp, score.counts.fn, percent(score.precision),
             percent(score.recall),
             f"{score.f1:.3f}", f"{score.frames_better} / {score.frames_worse}",
             "chosen" if score.share == blend.chosen else ""] for score in blend.shares]
    return ("<h2>Blend with the shipped model</h2><p>Each share of the fine-tune (0: the shipped model, 1: the "
            "fine-tune alone) scored on the valid split. Half and half ships unless another share makes fewer "
            "errors than it on enough valid frames (a one-sided sign test at 5 %: at least five frames better and "
            "none worse); then the best of those.</p>"
            + table(["share", "TP", "FP", "FN", "precision", "recall", "F1", "frames better / worse than 0.5", ""],
                    rows))


def _export(exported: ExportedModel) -> str:
    files = html.escape(str(exported.fp32)) + (f" and {html.escape(str(exported.int8))}" if exported.int8 else "")
    carried = ("the shipped model's range calibration and threshold" if exported.calibrated else
               "the shipped model's threshold; its range calibration was measured at another input width, so run "
               "<code>poles calibrate --model ... --embed ...</code> before ranging with it")
    check = exported.check
    if check is None:
        return f"<h2>Exported</h2><p>{files}, with {carried}; ONNX and PyTorch differ by at most " \
               f"{exported.onnx_difference or 0:.2g}.</p>"
    latency = ", ".join(f"{name} {ms:.1f} ms" for name, ms in check.latency_ms.items())
    int8 = "".join(f"; INT8 against FP32: {html.escape(verdict(agreement, problems))}"
                   for label, agreement, problems in check.comparisons() if "INT8" in label)
    return f"<h2>Exported</h2><p>{files}, with {carried}. Per frame on this machine: {latency}{int8}.</p>"
