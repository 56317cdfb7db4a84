"""A new venue: does ``poles finetune --model robot --unlabelled`` learn it from frames nobody labelled?

The venue is rendered: every pole in the paint measured on ``../shared/real-poles`` (a real team's poles), half the
backdrop frames back-lit, three frames in four over ``../shared/real-backgrounds``. N frames are the team's
recording (their labels are never read: only the images folder is passed), 200 more with labels are held out to
judge on. The robot model is fine-tuned on the recording alone for ``--minutes``; the shipped robot front end and
the fine-tune are judged on the venue's held-out frames and on the robot table's fresh sets over real backdrops and
ray-cast (F1, boxes matched by IoU >= 0.5, no camera pose, each at its own threshold).

Usage: python benchmarks/bench_new_venue.py [--frames 200 1000] [--minutes 10] [--out runs/new-venue]
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

os.environ.setdefault("YOLO_OFFLINE", "true")
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_robot_table import fresh_sets, scores  # noqa: E402  (a sibling benchmark: its sets and its scoring)

REPOSITORY = Path(__file__).resolve().parents[1]
SHARED = REPOSITORY.parent / "shared"
#: Seeds of the venue's recording and of its held-out frames (never the robot table's).
RECORDING_SEED, HELD_OUT_SEED = 5301, 5302
HELD_OUT_FRAMES = 200


def venue(folder: Path, frames: int, seed: int, split: str) -> Path:
    """The venue's frames rendered once into ``folder``."""
    from detector.synth.backdrops import scan_backdrops
    from detector.synth.generate import SynthJob, generate_dataset
    from detector.synth.scene import SceneConfig
    from detector.synth.team_paint import measure_team_paint

    if (folder / "data.yaml").is_file():
        return folder
    paint = measure_team_paint(SHARED / "real-poles", splits=("test",))  # all its frames are in test
    config = SceneConfig(team_paint=paint.scene_paint(), team_paint_share=1.0, backlight_share=0.5)
    job = SynthJob(frames, seed, config=config, backgrounds=tuple(scan_backdrops(SHARED / "real-backgrounds" / "images")),
                   backdrop_share=0.75)
    return generate_dataset(folder, job, split=split)


def main() -> None:
    from detector.cli import main as poles

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, nargs="+", default=[200, 1000])
    parser.add_argument("--minutes", type=float, default=10.0)
    parser.add_argument("--out", type=Path, default=Path("runs/new-venue"))
    parser.add_argument("--sets", type=Path, default=Path("runs/table-sets"))
    args = parser.parse_args()
    held_out = venue(args.out / "held-out", HELD_OUT_FRAMES, HELD_OUT_SEED, "test")
    judged = {"the venue's held-out frames": held_out}
    judged.update({name: root for name, root in fresh_sets(args.sets, 400).items()
                   if name in ("over real backdrops", "ray-cast")})
    models = {"shipped-robot": "shipped-robot"}
    for frames in args.frames:
        recording = venue(args.out / f"recording-{frames}", frames, RECORDING_SEED, "train") / "train" / "images"
        run = args.out / f"finetune-{frames}"
        if not (run / "models" / "poles-robot-finetuned.onnx").is_file():
            assert poles(["finetune", "--model", "robot", "--unlabelled", str(recording), "--out", str(run),
                          "--minutes", f"{args.minutes:g}"]) == 0
        models[f"{frames} unlabelled frames"] = str(run / "models" / "poles-robot-finetuned.onnx")
    print("| robot model | " + " | ".join(f"F1 {name}" for name in judged) + " |")
    print("| --- |" + " --- |" * len(judged))
    for label, model in models.items():
        row = [scores(model, root, use_pose=False) for root in judged.values()]
        print(f"| {label} | " + " | ".join(f"{score['f1']:.3f} (TP {score['tp']} FP {score['fp']} FN {score['fn']})"
                                         for score in row) + " |", flush=True)


if __name__ == "__main__":
    main()
