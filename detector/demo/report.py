"""report.html: one self-contained page (images embedded) showing what every stage of the demo produced."""
from __future__ import annotations

import html
from pathlib import Path

from calibration.run import CalibrationResult
from detector.atomic import write_text
from detector.demo.budget import Budget
from detector.demo.results import AgainstShipped, DemoEvaluation, DemoResult, DemoSlam, DemoSpeed
from detector.evaluation.results import Evaluation
from detector.html_page import image, page, percent, table
from detector.speed import ATOM_FACTORS
from detector.stages import StageRecord
from export.run import AGREEMENT_ROWS, verdict


def _m(value: float | None, unit: str = "m", digits: int = 3) -> str:
    return f"{value:.{digits}f} {unit}" if value is not None else "-"


def write_report(out: Path, results: DemoResult, budget: Budget, timings: list[StageRecord]) -> Path:
    """Write ``out``/report.html from the stage results."""
    parts = [f"<h1>poles demo: {budget.name} budget</h1>",
             '<p class="note">Synthetic pole dataset rendered with a calibrated Nao camera, augmented as the 2024 '
             "thesis did, a YOLOv8 segmentation model trained on this CPU, exported to ONNX (FP32 and INT8), range "
             "calibration, evaluation as the thesis counted, and EKF SLAM on a walk rendered image by image; the "
             "robot front end that runs on the Nao is evaluated, mapped with and timed beside the trained model.</p>",
             _stages(timings, budget, _training_hours(results, budget)), _data(results), _training(results, budget),
             _export(results), _calibration(results.calibrate), _evaluation(results.evaluate), _slam(results.slam),
             _speed(results.speed)]
    return write_text(Path(out) / "report.html", page("poles demo report", parts))


def _training_hours(results: DemoResult, budget: Budget) -> float | None:
    """The time cap the first model trained under (None: it trained for the budget's epochs)."""
    minutes = results.trainings[0].minutes if results.trainings else None
    return minutes / 60 if minutes else budget.train_hours


def _stages(timings: list[StageRecord], budget: Budget, train_hours: float | None) -> str:
    rows = [[r.name, r.status + ("" if r.ran else " (reused)"), f"{r.seconds:.0f}"] for r in timings]
    total = sum(r.seconds for r in timings)
    return ("<h2>Stages and time taken</h2>" + table(["stage", "status", "seconds"], rows)
            + f"<p>Total {total / 60:.1f} min. Budget: {budget.images} images, {budget.copies} augmented "
            f"copies each, {', '.join(budget.models)} at {budget.imgsz} px"
            + (f" for {train_hours * 60:.1f} min of training" if train_hours else f" for {budget.epochs} epochs")
            + (f" (what the other stages left of {budget.whole_minutes:g} minutes)" if budget.whole_minutes else "")
            + f", exported at {budget.export_hw[1]}x{budget.export_hw[0]}.</p>"
            + f"<p class='note'>{html.escape(budget.rationale)}</p>")


def _data(results: DemoResult) -> str:
    d, a = results.data, results.augment
    return ("<h2>Dataset and augmentation</h2>"
            + table(["images", "train", "valid", "test", "poles", "frames without a pole"],
                    [[d.images, d.frames.train, d.frames.valid, d.frames.test, d.poles, d.empty]])
            + image(d.preview, "dataset preview: labels drawn")
            + f"<p>Augmentation: {a.train_images_in} training images -> {a.train_images_out} "
            f"({a.copies} copies each); instances kept {a.instances_kept}, dropped {a.instances_dropped}. "
            "Operations used: " + ", ".join(f"{k} {v}" for k, v in sorted(a.operations.items())) + ".</p>"
            + image(a.preview or "", "augmentation preview: original and three copies per row"))


def _training(results: DemoResult, budget: Budget) -> str:
    out = "<h2>Training</h2>"
    for t in results.trainings:
        best = t.best
        out += (f"<p>{html.escape(t.model)} at {budget.imgsz} px: best epoch {best.epoch} of {best.epochs} "
                f"(chosen on the validation split): box mAP50 {best.box_map50:.3f}, mask mAP50 {best.mask_map50:.3f}, "
                f"mask mAP50-95 {best.mask_map50_95:.3f}.</p>" + image(t.curves, "training curves"))
    return out


def _export(results: DemoResult) -> str:
    out = "<h2>Export and agreement</h2>"
    for report in results.exports:
        rows = [[label, *(cell(agreement) for cell in AGREEMENT_ROWS.values()), verdict(agreement, problems)]
                for label, agreement, problems in report.comparisons()]
        out += (f"<p>{html.escape(report.onnx.name)} ({report.width}x{report.input_hw[0]} input), checked on "
                f"{report.verify_frames} frames:</p>"
                + table(["comparison", *AGREEMENT_ROWS, "verdict"], rows)
                + "<p>Front end per frame: " + ", ".join(f"{k} {v:.1f} ms" for k, v in report.latency_ms.items())
                + f"; recommended: {report.recommended.upper()}.</p>")
    return out


def _calibration(result: CalibrationResult) -> str:
    c = result.report
    laws = [[name, f"{law.a:.4g}", f"{law.b:.4f}", f"{law.r2:.4f}", percent(law.relative_std)]
            for name, law in c.laws().items()]
    errors = [[r.label, r.samples, *(f"{v:.1f} %" for v in (r.width, r.height, r.rule, r.fused))]
              for r in c.errors_by_range]
    return ("<h2>Range calibration</h2>"
            + f"<p>{c.samples} poles of known range ({html.escape(c.source)}); range = a * px^b, pixels at "
            f"{c.reference_width_px} px image width (thesis at 640x480: width 70.057 px^-1.109, height 209.16 "
            "px^-0.965).</p>"
            + table(["law", "a", "b", "R^2", "relative std"], laws)
            + table(["true range (m)", "poles", "width", "height", "thesis rule", "fused"], errors)
            + (image(result.plot, "calibration fit") if result.plot else ""))


def _localisation(m: Evaluation) -> str:
    if m.mean_iou is not None:
        return f"IoU {m.mean_iou:.4f}"
    return _m(m.divide_pixel_error.mean if m.divide_pixel_error else None, unit="px", digits=2)


def _evaluation(evaluation: DemoEvaluation) -> str:
    header = ["front end", "images", "TP", "FP", "FN", "TN", "precision", "recall", "F1", "localisation", "mAP50",
              "range error (median)", "bearing error (median)"]
    cells = []
    for front_end in evaluation.front_ends:
        r, counts = front_end.evaluation, front_end.evaluation.counts
        cells.append([r.model, r.images, counts.tp, counts.fp, counts.fn, counts.tn, percent(r.precision),
                      percent(r.recall), f"{r.f1:.3f}", _localisation(r), f"{r.map.map50:.3f}" if r.map else "-",
                      _m(r.range_error.median if r.range_error else None),
                      _m(r.bearing_error.median if r.bearing_error else None, "deg", 2)])
    out = ("<h2>Evaluation on held-out frames</h2><p>Counted per image as the thesis did (table 4.2): a detection "
           "is a true positive when its class matches and its mask overlaps the label with IoU &ge; 0.5; a frame "
           f"with no pole and no detection is a true negative. Confidence threshold {evaluation.conf:.2f} "
           f"({html.escape(evaluation.conf_source)}). The rows marked <i>boxes, pose</i> run as on the robot: each "
           "frame with its camera pose (the band below the horizon, the ground-plane gate), every detection matched "
           "to the labels by its box (IoU &ge; 0.5), since the robot front end draws boxes, not masks; each at its "
           "own threshold. Thesis on "
           "real frames: colour filter 97.4 % / 65.8 %, YOLOv8s 92.9 % / 98.3 % (IoU 0.8714), YOLOv8m 94.4 % / "
           "99.2 % (IoU 0.8783).</p>" + table(header, cells) + _against_shipped(evaluation.against_shipped))
    for front_end in evaluation.front_ends:
        folder = front_end.folder
        examples = sorted((folder / "errors").glob("*.jpg"))[:2]
        out += (f"<h3>{html.escape(front_end.evaluation.model)}</h3><div class='row'>"
                + image(folder / "per_image.png", "per image") + image(folder / "sweep.png", "confidence sweep")
                + image(folder / "confusion.png", "confusion matrix")
                + image(folder / "recall_by_width.png", "recall by pole width") + "</div>")
        if examples:
            out += ("<p class='note'>False positives (red) and misses (yellow), matched detections in blue:</p>"
                    "<div class='row'>" + "".join(image(e, e.name, 640) for e in examples) + "</div>")
    return out


def _against_shipped(gain: AgainstShipped) -> str:
    """What the training bought: the trained model's F1 less the shipped model's, as installed, on the same frames."""
    change = gain.change
    verdict_text = ("better than" if change.low > 0 else "worse than" if change.high < 0 else
                    "not distinguishable from")
    return (f"<p>Against the shipped model as installed ({html.escape(gain.reference)}, at its own threshold "
            f"{gain.reference_conf:.2f}), {html.escape(gain.model)} changes F1 by "
            f"{change.difference:+.3f} (95 % interval over these frames {change.low:+.3f} to {change.high:+.3f}): "
            f"{verdict_text} it. Keep whichever scores better on your own held-out frames; on rendered frames like its "
            "training data a short fine-tune seldom improves the shipped model (docs/history.md, "
            "\"What a short CPU fine-tune does to the shipped model\").</p>")


def _speed(speed: DemoSpeed) -> str:
    rows = [[row.front_end, row.model, _ms(row.capped_ms), _atom(row.capped_ms), _ms(row.uncapped_ms),
             html.escape(row.note) or "-"] for row in speed.rows]
    return ("<h2>Speed on the robot</h2>"
            f"<p>Each front end as naoslam runs it on the Nao (one thread, {html.escape(speed.engine)}), on "
            f"{speed.frames} held-out frames with their camera poses, timed in a fresh process with numpy, OpenCV "
            "and OpenVINO capped at the Atom's instruction set (SSE4.1, no AVX) and in one without the cap. The Atom "
            "E3845 estimate is the capped time x7-10 (docs/robot-model.md); a camera frame comes every 33 ms.</p>"
            + table(["front end", "model", "ms per frame, capped", "Atom E3845 estimate", "ms per frame, uncapped",
                     "note"], rows))


def _ms(value: float | None) -> str:
    return f"{value:.1f}" if value is not None else "-"


def _atom(capped_ms: float | None) -> str:
    if capped_ms is None:
        return "-"
    low, high = (capped_ms * factor for factor in ATOM_FACTORS)
    return f"{low:.0f}-{high:.0f} ms"


def _slam(s: DemoSlam) -> str:
    out = (f"<h2>EKF SLAM on a simulated walk</h2><p>A square walk of {s.walk_seconds:.0f} seconds on the SPL field "
           f"with the six poles; frames ray-cast along it go through each front end into {html.escape(s.backend)}.</p>")
    rows = [[run.front_end, run.measurements, _m(run.figures.robot_error), _m(run.figures.landmark_error),
             _m(run.figures.odometry_error), f"{run.figures.nees:.1f}" if run.figures.nees is not None else "-"]
            for run in s.runs]
    out += table(["front end", "measurements", "robot error", "landmark error", "odometry alone", "NEES"], rows)
    for run in s.runs:
        out += f"<h3>through the {run.front_end}</h3><div class='row'>" + image(run.map, "map") + \
               image(run.errors, "errors") + "</div>"
    for title, backends in s.tables.items():
        out += f"<h3>Back ends: {html.escape(title)}</h3>" + table(
            ["back end", "seeds", "landmark mean", "robot mean", "odometry alone", "NEES (median)"],
            [[r.backend, r.seeds, *(f"{v:.4f}" if v is not None else "-" for v in
                                    (r.landmark_error, r.robot_error, r.odometry_error)),
              f"{r.nees:.1f}" if r.nees is not None else "-"] for r in backends])
    out += ("<p class='note'>Thesis (Gutmann data, first 10 min): classic EKF landmark 0.299 m / robot 0.149 m; "
            "FEJ-EKF 0.166 / 0.107; minimal view n=3 0.137 / 0.097. Nao square walk: robot 0.174 m (FEJ n=5 + "
            "YOLOv8s), odometry alone 0.504 m.</p>")
    return out
