"""Fine-tuning benchmarks.

``real`` mode: the job ``poles finetune`` does, on real Nao frames, as group hold-outs on ``../shared/real-poles``:
fine-tune on the 6 calibration shots and test on the 8 walk frames, then the other way round. Each group runs the
whole ``poles finetune`` (its --minutes on every core), and the shipped model, the fine-tune and the chosen blend are
compared on the held-out group, on fresh rendered sets (everything, far poles) and, where
``../shared/real-backgrounds`` is present, on a set drawn over its frames of other rooms than the Dutch Nao Team's
field, half of it back-lit; one table. ``--own-field`` rehearses over that field's frames (``poles finetune
--backgrounds``), standing in for a team's own field without poles.
Usage: python benchmarks/bench_finetune.py real [--model accurate|robot] [--minutes 15] [--epochs N] [--frames 200] [--rehearsal-share S] [--own-field] [--freeze N]
       [--lr0 L] [--unlabelled] [--out FOLDER]

``rendered`` mode (the default): how good is a user's model after minutes of CPU training, from scratch against from
the shipped pole model? The "user" dataset is unlike the shipped model's training data: another seed, another camera (1280x960, the
documented 60.97 deg field of view instead of 56.3), rendered rooms only (no real backdrops). Each start trains
YOLOv8n-seg at 640 px, batch 8, for MINUTES[-1] minutes on every core; a snapshot of the weights at each mark in
MINUTES is evaluated on the test split (mask mAP50, precision and recall at 0.5, counted as `poles evaluate` does).
Usage: python benchmarks/bench_finetune.py [rendered] [MINUTES ...]   (default 5 15)
"""
from __future__ import annotations

import argparse
import copy
import json
import os
import shutil
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

os.environ.setdefault("YOLO_OFFLINE", "true")


def train_with_snapshots(data: Path, run: Path, weights: Path | None, minutes: list[float]) -> dict[float, Path]:
    """Train for ``minutes[-1]`` minutes; save the (EMA) weights the first time each mark is passed."""
    import torch
    from ultralytics import YOLO

    from detector.training.train import CpuSegmentationTrainer, use_all_cores

    use_all_cores()
    model = YOLO(str(weights) if weights else "yolov8n-seg.yaml", task="segment")
    marks, saved, start = sorted(minutes), {}, time.perf_counter()

    def snapshot(trainer) -> None:
        elapsed = (time.perf_counter() - start) / 60
        for mark in marks:
            if elapsed >= mark and mark not in saved:
                path = run.parent / f"{run.name}-{mark:g}min.pt"
                torch.save({"model": copy.deepcopy(trainer.ema.ema).half(), "train_args": vars(trainer.args)}, path)
                saved[mark] = path

    model.add_callback("on_fit_epoch_end", snapshot)
    model.train(data=str(data / "data.yaml"), epochs=1000, time=marks[-1] / 60, imgsz=640, batch=8, device="cpu",
                amp=False, plots=False, project=str(run.parent), name=run.name, exist_ok=True, cache=True,
                workers=0, trainer=CpuSegmentationTrainer, verbose=False)
    return saved


def main(minutes: list[float]) -> None:
    from detector.evaluation.predictors import TorchPredictor
    from detector.evaluation.run import evaluate
    from detector.synth.generate import SynthJob, generate_dataset
    from detector.model_files import SHIPPED_WEIGHTS

    with tempfile.TemporaryDirectory() as tmp:
        data = generate_dataset(Path(tmp) / "user", SynthJob(200, seed=4242, width=1280, height=960, hfov_deg=60.97),
                                progress=False)
        print(f"{os.cpu_count()} cores; user dataset: 200 frames 1280x960 (140 train / 40 test / 20 valid); "
              f"YOLOv8n-seg at 640, batch 8")
        for start, weights in (("scratch", None), ("shipped", SHIPPED_WEIGHTS)):
            snapshots = train_with_snapshots(data, Path(tmp) / f"run-{start}", weights, minutes)
            for mark in minutes:
                if mark not in snapshots:
                    print(f"{start:>8} after {mark:g} min: no epoch ended after that mark")
                    continue
                m = evaluate(TorchPredictor(snapshots[mark]), data, Path(tmp) / f"eval-{start}-{mark}", "test", 0.5,
                             progress=False)
                print(f"{start:>8} after {mark:g} min: mask mAP50 {m.map.map50 if m.map else 0:.3f}, precision "
                      f"{m.precision:.1%}, recall {m.recall:.1%} (test split, conf 0.5)", flush=True)


SHARED = Path(__file__).resolve().parents[1].parent / "shared"
#: The two groups of ../shared/real-poles: the calibration shots and the walk frames, by file-name prefix.
GROUPS = {"calibration shots": "calib_", "walk frames": "walk_"}


#: The frames of ``../shared/real-backgrounds`` from one team's field (the Dutch Nao Team's); the rest are other rooms.
OWN_FIELD_PREFIX = "Datasets__NaoLeague"


def split_backgrounds(backgrounds: Path) -> tuple[tuple[Path, ...], tuple[Path, ...]]:
    """``backgrounds``' frames of the own field, and of the other rooms."""
    from detector.synth.backdrops import scan_backdrops

    frames = scan_backdrops(backgrounds)
    own = tuple(frame for frame in frames if frame.name.startswith(OWN_FIELD_PREFIX))
    return own, tuple(frame for frame in frames if frame not in own)


def linked_folder(frames: tuple[Path, ...], out: Path) -> Path:
    """A fresh folder ``out`` of links to ``frames`` (what ``--backgrounds`` reads)."""
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir(parents=True)
    for frame in frames:
        (out / frame.name).symlink_to(frame.resolve())
    return out


def group_export(real: Path, train_prefix: str, test_prefix: str, out: Path) -> Path:
    """A Roboflow-layout export of ``real``'s frames: those named ``train_prefix*`` in train, ``test_prefix*`` in test
    (no valid split: ``poles finetune`` makes one, as for a team's export without one)."""
    from detector.datasets.intake import open_dataset
    from detector.datasets.io import DatasetWriter

    dataset = open_dataset(real, progress=False)
    with DatasetWriter(out, force=True, protect=dataset.input_folders()) as writer:
        for sample in dataset.samples:
            for split, prefix in (("train", train_prefix), ("test", test_prefix)):
                if sample.image is not None and sample.image.name.startswith(prefix):
                    writer.add(split, sample.image.name, sample.image, sample.instances)
    return out


def real_mode(argv: list[str]) -> None:
    from detector.evaluation.paired import REFERENCE
    from detector.finetune.judge import compare_models, render_set
    from detector.finetune.pipeline import judging_predictor, run_finetune
    from detector.finetune.recipe import STARTING_MODELS, FinetuneRecipe

    parser = argparse.ArgumentParser(prog="bench_finetune.py real")
    defaults = FinetuneRecipe()
    parser.add_argument("--model", choices=STARTING_MODELS, default=defaults.model)
    parser.add_argument("--minutes", type=float, default=defaults.minutes)
    parser.add_argument("--epochs", type=int, help="at most this many epochs (default: the model's)")
    parser.add_argument("--frames", type=int, default=200, help="frames per rendered set")
    parser.add_argument("--rehearsal-share", type=float, help="default: the model's")
    parser.add_argument("--freeze", type=int, default=defaults.freeze)
    parser.add_argument("--lr0", type=float, default=defaults.lr0)
    parser.add_argument("--warmup-epochs", type=float, default=defaults.warmup_epochs)
    parser.add_argument("--own-field", action="store_true",
                        help="rehearse over ../shared/real-backgrounds' frames of the Dutch Nao Team's field")
    parser.add_argument("--unlabelled", action="store_true",
                        help="the training group's frames without their labels (`poles finetune --unlabelled`, the "
                             "accurate model as teacher), the test group's as the labelled export")
    parser.add_argument("--out", type=Path, help="keep every run here (default: a temporary folder)")
    args = parser.parse_args(argv)
    real, backgrounds = SHARED / "real-poles", SHARED / "real-backgrounds" / "images"
    if not (real / "data.yaml").is_file():
        sys.exit(f"{real}: not here - the real mode needs ../shared/real-poles")
    if args.own_field and not backgrounds.is_dir():
        sys.exit(f"{backgrounds}: not here - --own-field needs ../shared/real-backgrounds")
    with tempfile.TemporaryDirectory() as tmp:
        root = args.out or Path(tmp)
        own_field, other_rooms = split_backgrounds(backgrounds) if backgrounds.is_dir() else ((), ())
        recipe = FinetuneRecipe(model=args.model, minutes=args.minutes, epochs=args.epochs,
                                rehearsal_share=args.rehearsal_share,
                                backgrounds=str(linked_folder(own_field, root / "own-field")) if args.own_field
                                else None, freeze=args.freeze,
                                lr0=args.lr0, warmup_epochs=args.warmup_epochs, evaluation_frames=args.frames)
        rows, timings = [], {}
        for train_group, test_group in (tuple(GROUPS), tuple(reversed(GROUPS))):
            name = f"{train_group} -> {test_group}"
            folder = root / name.split()[0]
            shutil.rmtree(folder, ignore_errors=True)
            if args.unlabelled:
                export = group_export(real, "-", GROUPS[test_group], folder / "export")  # no frame starts with "-"
                frames = linked_folder(tuple(sorted((real / "test" / "images").glob(f"{GROUPS[train_group]}*"))),
                                       folder / "unlabelled")
                result = run_finetune(export, folder / "run", replace(recipe, unlabelled=str(frames)))
            else:
                export = group_export(real, GROUPS[train_group], GROUPS[test_group], folder / "export")
                result = run_finetune(export, folder / "run", recipe)
            timings[name] = result.seconds
            stages = result.stages
            group_rows = list(stages.evaluate.rows)
            if other_rooms:
                models = {REFERENCE: recipe.start.weights, "fine-tune": stages.train.weights,
                          group_rows[-1].model: stages.blend.weights}
                backdrop_set = render_set(folder / "backdrops", args.frames, 0.0, 9103, other_rooms,
                                          backlight_share=0.5)
                group_rows += compare_models(models, {"over other rooms, half back-lit": (backdrop_set, "test", None)},
                                             folder / "backdrops-evaluation", stages.evaluate.conf,
                                             judging_predictor(recipe))
            rows += [(name, row) for row in group_rows]
        settings = recipe.settings()
        print(f"\nrecipe: {json.dumps(settings)}")
        print(f"{'group':<34} {'set':<32} {'model':<10} {'TP':>4} {'FP':>4} {'FN':>4} {'prec':>7} {'recall':>7} "
              f"{'F1':>6} {'F1 change (95 %)':>22} {'recall <16px':>13}")
        for group, r in rows:
            change = r.f1_change
            text = (f"{100 * change.difference:+.1f} ({100 * change.low:+.1f}..{100 * change.high:+.1f})"
                    if change else "-")
            small = f"{100 * r.recall_under_16px:.1f} %" if r.recall_under_16px is not None else "-"
            print(f"{group:<34} {r.set_name:<32} {r.model:<10} {r.counts.tp:>4} {r.counts.fp:>4} {r.counts.fn:>4} "
                  f"{100 * r.precision:>6.1f}% {100 * r.recall:>6.1f}% {r.f1:>6.3f} {text:>22} {small:>13}")
        for name, seconds in timings.items():
            print(f"{name}: " + ", ".join(f"{stage} {s:.0f} s" for stage, s in seconds.items())
                  + f"; total {sum(seconds.values()) / 60:.1f} min")
        written = [{"group": group, **row.to_json()} for group, row in rows]
        (root / "bench_finetune_real.json").write_text(json.dumps({"recipe": settings, "rows": written,
                                                                   "seconds": timings}, indent=1))


if __name__ == "__main__":
    if sys.argv[1:2] == ["real"]:
        real_mode(sys.argv[2:])
    else:
        main([float(v) for v in sys.argv[1:] if v != "rendered"] or [5.0, 15.0])
