"""report.html: one self-contained page (images embedded) showing what every stage of the demo produced."""
from __future__ import annotations

import html
from pathlib import Path

from detector.atomic import write_text
from detector.html_page import image, page, percent, table
from detector.stages import StageRecord

def _m(stats: dict | None, key: str = "mean", unit: str = "m", digits: int = 3) -> str:
    return f"{stats[key]:.{digits}f} {unit}" if stats else "-"


def write_report(out: Path, results: dict, timings: list[StageRecord]) -> Path:
    """Write ``out``/report.html from the stage results."""
    budget = results["budget"]
    parts = [f"<h1>poles demo: {budget['name']} budget</h1>",
             '<p class="note">Synthetic pole dataset rendered with a calibrated Nao camera, augmented as the 2024 '
             "thesis did, a YOLOv8 segmentation model trained on this CPU, exported to ONNX (FP32 and INT8), range "
             "calibration, evaluation as the thesis counted, and EKF SLAM on a walk rendered image by image.</p>",
             _stages(timings, budget, _training_hours(results)), _data(results), _training(results), _export(results),
             _calibration(results["calibrate"]), _evaluation(results["evaluate"]), _slam(results["slam"])]
    return write_text(Path(out) / "report.html", page("poles demo report", parts))


def _training_hours(results: dict) -> float | None:
    """The time cap the first model trained under (None: it trained for the budget's epochs)."""
    first = next(key for key in results if key.startswith("train "))
    return results[first].get("time_hours", results["budget"]["train_hours"])


def _stages(timings: list[StageRecord], budget: dict, train_hours: float | None) -> str:
    rows = [[r.name, r.status + ("" if r.ran else " (reused)"), f"{r.seconds:.0f}"] for r in timings]
    total = sum(r.seconds for r in timings)
    return ("<h2>Stages and time taken</h2>" + table(["stage", "status", "seconds"], rows)
            + f"<p>Total {total / 60:.1f} min. Budget: {budget['images']} images, {budget['copies']} augmented "
            f"copies each, {', '.join(budget['models'])} at {budget['imgsz']} px"
            + (f" for {train_hours * 60:.1f} min of training" if train_hours else f" for {budget['epochs']} epochs")
            + (f" (what the other stages left of {budget['whole_minutes']:g} minutes)"
               if budget.get("whole_minutes") else "")
            + f", exported at {budget['export_hw'][1]}x{budget['export_hw'][0]}.</p>"
            + f"<p class='note'>{html.escape(budget['rationale'])}</p>")


def _data(results: dict) -> str:
    d, a = results["data"], results["augment"]
    return ("<h2>Dataset and augmentation</h2>"
            + table(["images", "train", "valid", "test", "poles", "frames without a pole"],
                     [[d["images"], d["train"], d["valid"], d["test"], d["poles"], d["empty"]]])
            + image(d["preview"], "dataset preview: labels drawn")
            + f"<p>Augmentation: {a['train_images_in']} training images -> {a['train_images_out']} "
            f"({a['copies']} copies each); instances kept {a['instances_kept']}, dropped {a['instances_dropped']}. "
            "Operations used: " + ", ".join(f"{k} {v}" for k, v in sorted(a["operations"].items())) + ".</p>"
            + image(a.get("preview", ""), "augmentation preview: original and three copies per row"))


def _training(results: dict) -> str:
    out = "<h2>Training</h2>"
    for name, t in results.items():
        if not name.startswith("train "):
            continue
        out += (f"<p>{html.escape(t['model'])} at {t['imgsz']} px: best epoch {t['best_epoch']} of {t['epochs']} "
                f"(chosen on the validation split): box mAP50 {t['mAP50(B)']:.3f}, mask mAP50 {t['mAP50(M)']:.3f}, "
                f"mask mAP50-95 {t['mAP50-95(M)']:.3f}.</p>" + image(t["curves"], "training curves"))
    return out


def _export(results: dict) -> str:
    out = "<h2>Export and agreement</h2>"
    for name, r in results.items():
        if not name.startswith("export "):
            continue
        rows = []
        for key, label in (("fp32_vs_pytorch", "ONNX FP32 vs PyTorch"), ("int8_vs_fp32", "ONNX INT8 vs FP32")):
            if key in r:
                a = r[key]
                problems = r["fp32_problems" if key.startswith("fp32") else "int8_problems"]
                rows.append([label, f"{a['reference']} / {a['candidate']}", a["matched"], a["class_mismatches"],
                             f"{a['box_iou_min']:.4f} / {a['box_iou_mean']:.4f}",
                             f"{a['mask_iou_min']:.4f} / {a['mask_iou_mean']:.4f}", f"{a['score_diff_max']:.4f}",
                             "; ".join(problems) or "agrees"])
        out += (f"<p>{html.escape(Path(r['onnx']).name)} ({r['input_hw'][1]}x{r['input_hw'][0]} input), checked on "
                f"{r['verify_frames']} frames:</p>"
                + table(["comparison", "detections (ref / new)", "matched", "class changes", "box IoU min / mean",
                          "mask IoU min / mean", "max score diff", "verdict"], rows)
                + "<p>Front end per frame: " + ", ".join(f"{k} {v:.1f} ms" for k, v in r["latency_ms"].items())
                + f"; recommended: {r['recommended'].upper()}.</p>")
    return out


def _calibration(c: dict) -> str:
    laws = [[key, f"{c[key]['a']:.4g}", f"{c[key]['b']:.4f}", f"{c[key]['r2']:.4f}", percent(c[key]["relative_std"])]
            for key in ("width", "height", "colour") if key in c]
    errors = [[r["range_m"], r["samples"], *(f"{r[m]:.1f} %" for m in ("width", "height", "rule", "fused"))]
              for r in c["errors_by_range"]]
    return ("<h2>Range calibration</h2>"
            + f"<p>{c['samples']} poles of known range ({html.escape(c['source'])}); range = a * px^b, pixels at "
            f"{c['reference_width_px']} px image width (thesis at 640x480: width 70.057 px^-1.109, height 209.16 "
            "px^-0.965).</p>"
            + table(["law", "a", "b", "R^2", "relative std"], laws)
            + table(["true range (m)", "poles", "width", "height", "thesis rule", "fused"], errors)
            + image(c["plot"], "calibration fit"))


def _evaluation(evaluation: dict) -> str:
    rows = evaluation["rows"]
    header = ["front end", "images", "TP", "FP", "FN", "TN", "precision", "recall", "localisation", "mAP50",
              "range error (median)", "bearing error (median)"]
    cells = [[r["model"], r["images"], r["tp"], r["fp"], r["fn"], r["tn"], percent(r["precision"]), percent(r["recall"]),
              f"IoU {r['mean_iou']:.4f}" if r.get("mean_iou") is not None else _m(r.get("divide_pixel_error"),
                                                                                     unit="px", digits=2),
              f"{r['map50']:.3f}" if "map50" in r else "-", _m(r.get("range_error"), "median"),
              _m(r.get("bearing_error"), "median", "deg", 2)] for r in rows]
    out = ("<h2>Evaluation on held-out frames</h2><p>Counted per image as the thesis did (table 4.2): a detection "
           "is a true positive when its class matches and its mask overlaps the label with IoU &ge; 0.5; a frame "
           f"with no pole and no detection is a true negative. Confidence threshold {evaluation['conf']:.2f} "
           f"({html.escape(evaluation['conf_source'])}). Thesis on "
           "real frames: colour filter 97.4 % / 65.8 %, YOLOv8s 92.9 % / 98.3 % (IoU 0.8714), YOLOv8m 94.4 % / "
           "99.2 % (IoU 0.8783).</p>" + table(header, cells) + _against_shipped(evaluation["against_shipped"]))
    for r in rows:
        folder = Path(r["folder"])
        examples = sorted((folder / "errors").glob("*.jpg"))[:2]
        out += (f"<h3>{html.escape(r['model'])}</h3><div class='row'>" + image(folder / "per_image.png", "per image")
                + image(folder / "sweep.png", "confidence sweep") + image(folder / "confusion.png", "confusion matrix")
                + image(folder / "recall_by_width.png", "recall by pole width") + "</div>")
        if examples:
            out += ("<p class='note'>False positives (red) and misses (yellow), matched detections in blue:</p>"
                    "<div class='row'>" + "".join(image(e, e.name, 640) for e in examples) + "</div>")
    return out


def _against_shipped(gain: dict) -> str:
    """What the training bought: the trained model's F1 less the shipped model's, as installed, on the same frames."""
    verdict = ("better than" if gain["low"] > 0 else "worse than" if gain["high"] < 0 else
               "not distinguishable from")
    return (f"<p>Against the shipped model as installed ({html.escape(gain['reference'])}, at its own threshold "
            f"{gain['reference_conf']:.2f}), "
            f"{html.escape(gain['model'])} changes F1 by "
            f"{gain['difference']:+.3f} (95 % interval over these frames {gain['low']:+.3f} to {gain['high']:+.3f}): "
            f"{verdict} it. Keep whichever scores better on your own held-out frames; on rendered frames like its "
            "training data a short fine-tune seldom improves the shipped model (docs/history.md, "
            "\"What a short CPU fine-tune does to the shipped model\").</p>")


def _slam(s: dict) -> str:
    length = f" of {s['walk_seconds']:.0f} seconds" if "walk_seconds" in s else ""  # absent from older summaries
    out = (f"<h2>EKF SLAM on a simulated walk</h2><p>A square walk{length} on the SPL field with the six poles; "
           f"frames ray-cast along it go through each front end into {html.escape(s['backend'])}.</p>")
    rows = []
    for name in ("model", "colour filter"):
        m = s[name]["metrics"]
        rows.append([name, s[name]["measurements"], _m(m.get("robot_error")), _m(m.get("landmark_error")),
                     _m(m.get("odometry_error")), f"{m['nees']['mean']:.1f}" if "nees" in m else "-"])
    out += table(["front end", "measurements", "robot error", "landmark error", "odometry alone", "NEES"], rows)
    for name in ("model", "colour filter"):
        out += f"<h3>through the {name}</h3><div class='row'>" + image(s[name]["map"], "map") + \
               image(s[name]["errors"], "errors") + "</div>"
    for title, backends in s["tables"].items():
        out += f"<h3>Back ends: {html.escape(title)}</h3>" + table(
            ["back end", "seeds", "landmark mean", "robot mean", "odometry alone", "NEES (median)"],
            [[r["backend"], r["seeds"], *(f"{r[k]:.4f}" if k in r else "-" for k in
                                          ("landmark_error", "robot_error", "odometry_error")),
              f"{r['nees']:.1f}" if "nees" in r else "-"] for r in backends])
    out += ("<p class='note'>Thesis (Gutmann data, first 10 min): classic EKF landmark 0.299 m / robot 0.149 m; "
            "FEJ-EKF 0.166 / 0.107; minimal view n=3 0.137 / 0.097. Nao square walk: robot 0.174 m (FEJ n=5 + "
            "YOLOv8s), odometry alone 0.504 m.</p>")
    return out
