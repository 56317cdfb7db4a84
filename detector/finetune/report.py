"""report.html of a fine-tune: what it gained on the team's own held-out frames and what it lost on rendered frames
unlike them, beside the stages, the paint, the training curves and the blend that was chosen."""
from __future__ import annotations

import html
from pathlib import Path

from detector.atomic import write_text
from detector.html_page import image, page, percent, table
from detector.stages import StageRecord


def write_report(path: Path, results: dict, timings: list[StageRecord]) -> Path:
    """Write the report of a fine-tune's ``results`` (``pipeline.run_finetune``) to ``path``."""
    start = results["recipe"].get("model", "accurate")
    parts = [f"<h1>poles finetune: {html.escape(results['export']['export'])}</h1>",
             f"<p class='note'>The shipped {html.escape(start)} model, fine-tuned on your frames.</p>",
             _verdict(results["evaluate"]),
             _evaluation(results["evaluate"]), _stages(timings, results["recipe"]), _data(results),
             _training(results["train"]), _blend(results["blend"]), _export(results["export model"])]
    return write_text(path, page("poles finetune report", parts))


def changes(evaluation: dict) -> list[str]:
    """One line per rendered or held-out set: the chosen model's F1 change against the shipped model, 95 % interval."""
    lines = []
    for row in evaluation["rows"]:
        if row["model"].startswith("blend") and "f1_change" in row:
            change = row["f1_change"]
            lines.append(f"{row['set']}: F1 {100 * change['difference']:+.1f} points (95 % {100 * change['low']:+.1f} "
                         f"to {100 * change['high']:+.1f}) against the shipped model")
    return lines


def _verdict(evaluation: dict) -> str:
    items = "".join(f"<li>{html.escape(line)}</li>" for line in changes(evaluation))
    return ("<h2>What the fine-tune changed</h2><p>The model that ships from this run (the blend) against the shipped "
            f"model, both at its threshold {evaluation['conf']:.2f}:</p><ul>{items}</ul>")


def _evaluation(evaluation: dict) -> str:
    header = ["set", "model", "images", "TP", "FP", "FN", "TN", "precision", "recall", "F1",
              "F1 change (95 %)", "recall < 16 px"]
    rows = []
    for r in evaluation["rows"]:
        change = r.get("f1_change")
        rows.append([r["set"], r["model"], r["images"], r["tp"], r["fp"], r["fn"], r["tn"], percent(r["precision"]),
                     percent(r["recall"]), f"{r['f1']:.3f}",
                     f"{100 * change['difference']:+.1f} ({100 * change['low']:+.1f} to {100 * change['high']:+.1f})"
                     if change else "-",
                     f"{percent(r['recall_under_16px'])} of {r['small_labels']}" if r["small_labels"] else "-"])
    note = ("Counted per image as the thesis did: a detection is a true positive when its class matches and its mask "
            "overlaps the label with IoU &ge; 0.5. The F1 change is against the shipped model on the same frames, its "
            "interval drawn over frames. The rendered sets were rendered for this evaluation and never trained on"
            + (". There is no test split, so your frames are the valid split that also chose the blend: the figures "
               "on them flatter every fine-tuned model" if evaluation["held_out"] == "valid" else "") + ".")
    folders = "".join(f"<h3>{html.escape(r['set'])}: {html.escape(r['model'])}</h3><div class='row'>"
                      + image(Path(r["folder"]) / "per_image.png", "per image")
                      + image(Path(r["folder"]) / "recall_by_width.png", "recall by pole width") + "</div>"
                      for r in evaluation["rows"] if r["model"] != "fine-tune")
    return f"<h2>Evaluation</h2><p class='note'>{note}</p>" + table(header, rows) + folders


def _stages(timings: list[StageRecord], recipe: dict) -> str:
    rows = [[r.name, r.status + ("" if r.ran else " (reused)"), f"{r.seconds:.0f}"] for r in timings]
    settings = [[key.replace("_", " "), value] for key, value in recipe.items()]
    return ("<h2>Stages and time taken</h2>" + table(["stage", "status", "seconds"], rows)
            + f"<p>Total {sum(r.seconds for r in timings) / 60:.1f} min.</p>" + table(["recipe", "value"], settings))


def _swatch(rgb: list[float]) -> str:
    red, green, blue = (round(255 * c) for c in rgb)
    return (f"<span style='display:inline-block;width:2.5em;height:1.2em;vertical-align:middle;"
            f"background:rgb({red},{green},{blue})'></span>")


def _data(results: dict) -> str:
    export, paint, mix = results["export"], results["paint"], results["mix"]
    split_note = " (valid made from train: the export had none)" if export["valid_made_from_train"] else ""
    swatches = "".join(f"<tr><td>{letter}</td><td>{_swatch(rgb)}</td><td>{paint['measured_bands'][letter]}</td></tr>"
                       for letter, rgb in paint["letters"].items())
    return (f"<h2>Your frames</h2><p>train {export['train']}, valid {export['valid']}{split_note}, test "
            f"{export['test']}; {export['poles']} poles. Training set: {mix['train']} frames (your augmented frames and "
            f"{results['rehearsal']['frames']} rendered in your paint), validated on {mix['valid']}.</p>"
            f"<p>Paint measured on {paint['poles_measured']} poles ({paint['poles_skipped']} too small), "
            "white-balanced against each pole's base:</p>"
            f"<table><tr><th>band</th><th>paint</th><th>bands measured</th></tr>{swatches}</table>"
            "<div class='row'>" + image(results["augment"].get("preview", ""), "augmented copies")
            + image(results["rehearsal"].get("preview", ""), "rehearsal frames in your paint") + "</div>")


def _training(train: dict) -> str:
    return (f"<h2>Training</h2><p>{train['minutes']:.1f} minutes from the shipped checkpoint, {train['epochs']} epochs; "
            "the final weights are the fine-tune (a valid split of a few frames cannot choose an epoch).</p>"
            + image(train["curves"], "training curves"))


def _blend(blend: dict) -> str:
    rows = [[f"{row['share']:g}", row["tp"], row["fp"], row["fn"], percent(row["precision"]), percent(row["recall"]),
             f"{row['f1']:.3f}", f"{row['frames_better']} / {row['frames_worse']}",
             "chosen" if row["share"] == blend["chosen"] else ""] for row in blend["shares"]]
    return ("<h2>Blend with the shipped model</h2><p>Each share of the fine-tune (0: the shipped model, 1: the "
            "fine-tune alone) scored on the valid split. Half and half ships unless another share makes fewer "
            "errors than it on enough valid frames (a one-sided sign test at 5 %: at least five frames better and "
            "none worse); then the best of those.</p>"
            + table(["share", "TP", "FP", "FN", "precision", "recall", "F1", "frames better / worse than 0.5", ""],
                    rows))


def _export(export: dict) -> str:
    latency = ", ".join(f"{name} {ms:.1f} ms" for name, ms in (export.get("latency_ms") or {}).items())
    files = html.escape(export["fp32"]) + (f" and {html.escape(export['int8'])}" if export.get("int8") else "")
    problems = "; ".join(export.get("int8_problems") or []) or "agrees"
    int8 = f"; INT8 against FP32: {html.escape(problems)}" if export.get("int8") else ""
    carried = ("the shipped model's range calibration and threshold" if export.get("calibrated", True) else
               "the shipped model's threshold; its range calibration was measured at another input width, so run "
               "<code>poles calibrate --model ... --embed ...</code> before ranging with it")
    return (f"<h2>Exported</h2><p>{files}, with {carried}. Per frame on this machine: {latency}{int8}.</p>")
