"""The robot front end's deciding table: every robot front end on the same frames in one run, with the accurate model
as the yardstick.

Columns: the whole front end per 640x480 frame with the camera's pose, one thread, capped at the Atom's instruction
set (OpenVINO, numpy and OpenCV; ``bench_robot.py``'s workers) and uncapped; candidates per frame; F1 on four
fresh rendered sets (over real backdrops, ray-cast, far poles, back-lit poles), each frame with its camera pose as on
the robot and every front end matched to the labels by box IoU >= 0.5 (the two-stage front end gives boxes, so the
others are scored the same way); recall of poles at least and under 16 px wide over the sets; TP / FP / FN on
``../shared/real-poles`` (no pose recorded: the whole frame); and the training time on a two-core CPU as the model
records it. Each front end runs at its own operating threshold.

The sets are rendered when missing (400 frames each, the back-lit one 200; the seeds of docs/robot-model.md).
Usage: python benchmarks/bench_robot_table.py [--sets FOLDER] [--before OLD_ROBOT.onnx] [--model NEW.onnx] [--frames N]
"""
from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

os.environ.setdefault("YOLO_OFFLINE", "true")
REPOSITORY = Path(__file__).resolve().parents[1]
SHARED = REPOSITORY.parent / "shared"
#: The fresh sets: (name, seed, backdrop share, far share, back-lit share of the backdrop frames or None for the
#: renderer's own, share of the frames asked for), over ../shared/real-backgrounds where the backdrop share is > 0.
SETS = (("over real backdrops", 361, 1.0, 0.0, None, 1.0), ("ray-cast", 362, 0.0, 0.0, None, 1.0),
        ("far poles", 363, 0.75, 1.0, None, 1.0), ("back-lit", 364, 1.0, 0.0, 1.0, 0.5))
#: Width bins (``detector.evaluation.by_width``) that make up "under 16 px".
SMALL_BINS = ("< 10 px", "10-16 px")


def fresh_set(folder: Path, seed: int, backdrop_share: float, far_share: float, backlight_share: float | None,
              frames: int) -> Path:
    """The set rendered once into ``folder`` (kept for the next run)."""
    from detector.synth.backdrops import scan_backdrops
    from detector.synth.generate import SynthJob, generate_dataset
    from detector.synth.scene import SceneConfig

    if (folder / "data.yaml").is_file():
        return folder
    backgrounds = tuple(scan_backdrops(SHARED / "real-backgrounds" / "images")) if backdrop_share else ()
    config = SceneConfig(far_share=far_share) if backlight_share is None else \
        SceneConfig(far_share=far_share, backlight_share=backlight_share)
    job = SynthJob(frames, seed, backgrounds=backgrounds, backdrop_share=backdrop_share, config=config)
    return generate_dataset(folder, job, split="test")


def fresh_sets(folder: Path, frames: int) -> dict[str, Path]:
    """Every set of ``SETS`` by name, rendered once under ``folder``."""
    return {name: fresh_set(folder / f"fresh-{seed}", seed, backdrops, far, backlight, round(frames * share))
            for name, seed, backdrops, far, backlight, share in SETS}


def scores(model: str, dataset_root: Path, use_pose: bool) -> dict:
    """Every frame of the dataset through the front end at its operating threshold, matched by box IoU."""
    from detector.datasets.io import load_dataset
    from detector.datasets.truth import load_camera_poses, load_truth
    from detector.evaluation.by_width import recall_by_width
    from detector.evaluation.counting import totals
    from detector.evaluation.predictors import make_predictor
    from detector.evaluation.run import evaluate_frames
    from naoslam.shipped import DEFAULT_CONF

    predictor = make_predictor(model)
    predictor.matching = "box"
    dataset = load_dataset(dataset_root)
    samples = [sample for sample in dataset.samples if sample.image is not None]
    poses = load_camera_poses(dataset) if use_pose else {}
    images = evaluate_frames(predictor, samples, load_truth(dataset), f"{Path(model).name} on {dataset_root.name}",
                             poses=poses)
    conf = predictor.operating_conf or DEFAULT_CONF
    counts = totals(images, conf)
    widths = recall_by_width(images, conf)
    small = [row for row in widths if row.width in SMALL_BINS]
    large = [row for row in widths if row.width not in SMALL_BINS]
    return {**counts.to_json(), "f1": counts.precision_recall()[2], "conf": conf,
            "small": [sum(row.found for row in small), sum(row.labels for row in small)],
            "large": [sum(row.found for row in large), sum(row.labels for row in large)]}


def training_minutes(model: str) -> str:
    """The training time a model records in its metadata (the two-stage one does), else "-"."""
    from detector.model_files import read_info
    from naoslam.shipped import resolve_model

    record = read_info(resolve_model(model)).extra.get("training")
    return f"{record['minutes']:.0f} min ({record['hardware']})" if record else "-"


def main() -> None:
    sys.path.insert(0, str(Path(__file__).parent))
    sys.path.insert(0, str(REPOSITORY))
    from bench_robot import speed_table

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sets", type=Path, default=REPOSITORY / "runs" / "robot-table")
    parser.add_argument("--model", default="shipped-robot", help="the two-stage robot front end")
    parser.add_argument("--before", help="the robot model it replaces (ONNX), as `before`")
    parser.add_argument("--frames", type=int, default=400)
    parser.add_argument("--json", type=Path, help="also write the figures here")
    args = parser.parse_args()
    models = [("two-stage", args.model)] + ([("before", args.before)] if args.before else []) + \
        [("accurate (yardstick)", "shipped-int8")]
    sets = fresh_sets(args.sets, args.frames)
    real = SHARED / "real-poles"
    figures = {label: {"sets": {name: scores(model, folder, True) for name, folder in sets.items()},
                       "real": scores(model, real, False) if (real / "data.yaml").is_file() else None,
                       "training": training_minutes(model)} for label, model in models}
    capped, uncapped = speed_table(models, 20, 3)
    print("| front end | ms capped (with pose / without) | ms full ISA | candidates / frame | "
          + " | ".join(f"F1 {name}" for name in sets) + " | recall >= 16 px | recall < 16 px | real-poles TP / FP / FN"
          " | training (two-core CPU) |")
    print("|" + " --- |" * (8 + len(sets)))
    for label, _ in models:
        row = figures[label]
        key = f"{label}|openvino"
        large = [sum(row["sets"][n]["large"][i] for n in sets) for i in (0, 1)]
        small = [sum(row["sets"][n]["small"][i] for n in sets) for i in (0, 1)]
        real_cell = "/".join(str(row["real"][k]) for k in ("tp", "fp", "fn")) if row["real"] else "-"
        candidates = uncapped.get(f"{key}|candidates")
        print(f"| {label} | {_ms(capped.get(f'{key}|pose'))} / {_ms(capped.get(f'{key}|no pose'))} | "
              f"{_ms(uncapped.get(f'{key}|pose'))} | {f'{candidates:.1f}' if candidates else '-'} | "
              + " | ".join(f"{row['sets'][n]['f1']:.3f}" for n in sets)
              + f" | {100 * large[0] / large[1]:.1f} % | {100 * small[0] / small[1]:.1f} % | {real_cell} | "
              f"{row['training']} |")
    if args.json:
        args.json.write_text(json.dumps({"figures": figures, "capped": capped, "uncapped": uncapped}, indent=1))


def _ms(value) -> str:
    return f"{value:.1f}" if isinstance(value, float) else str(value)


if __name__ == "__main__":
    main()
