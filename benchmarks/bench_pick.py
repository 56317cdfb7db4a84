"""How much better than chance ``poles pick`` chooses the frames worth labelling.

On rendered sets whose truth is known (the robot table's fresh sets, rendered when missing), the shipped robot front
end's errors per frame (misses plus false positives at its operating threshold, no camera pose, boxes matched to the
labels by IoU >= 0.5 as the robot table counts them) on the frames ``poles pick`` picks, against the mean over every
frame of the set (what a random pick holds on average) and the 95th percentile of 1,000 random picks of the same
size. The issue's target: the picked frames hold at least three times the errors per frame of a random pick.

Usage: python benchmarks/bench_pick.py [--sets FOLDER] [--count 50] [--frames 400]
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

os.environ.setdefault("YOLO_OFFLINE", "true")
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_robot_table import fresh_sets  # noqa: E402  (a sibling benchmark: the same rendered sets)

#: Random picks drawn to compare with.
DRAWS = 1000


def robot_errors(dataset_root: Path) -> dict[str, int]:
    """Each frame's misses plus false positives of the shipped robot front end, by image name."""
    from detector.datasets.io import load_dataset
    from detector.datasets.truth import load_truth
    from detector.evaluation.predictors import make_predictor
    from detector.evaluation.run import evaluate_frames

    predictor = make_predictor("shipped-robot")
    predictor.matching = "box"
    dataset = load_dataset(dataset_root)
    samples = [sample for sample in dataset.samples if sample.image is not None]
    images = evaluate_frames(predictor, samples, load_truth(dataset), f"robot errors on {dataset_root.name}")
    counts = [image.counts(predictor.operating_conf) for image in images]
    return {sample.image.name: count.fp + count.fn for sample, count in zip(samples, counts)}


def picked_frames(dataset_root: Path, count: int) -> list[str]:
    """The names ``poles pick`` picks from the set's frames."""
    from detector.picking import pick_frames

    with tempfile.TemporaryDirectory() as folder:
        result = pick_frames(dataset_root / "test" / "images", Path(folder) / "upload", count)
    return [frame.name for frame in result.picked]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sets", type=Path, default=Path("runs/table-sets"))
    parser.add_argument("--count", type=int, default=50)
    parser.add_argument("--frames", type=int, default=400, help="frames per set when rendered")
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    print(f"| set | frames | picked | robot errors per picked frame | per frame, all | 95th pct of {DRAWS} random "
          "picks | ratio |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for name, root in fresh_sets(args.sets, args.frames).items():
        errors = robot_errors(root)
        picked = picked_frames(root, args.count)
        every = np.array(list(errors.values()), float)
        random = [every[rng.choice(len(every), len(picked), replace=False)].mean() for _ in range(DRAWS)]
        chosen = np.mean([errors[frame] for frame in picked])
        print(f"| {name} | {len(every)} | {len(picked)} | {chosen:.2f} | {every.mean():.2f} | "
              f"{np.percentile(random, 95):.2f} | {chosen / every.mean():.1f}x |", flush=True)


if __name__ == "__main__":
    main()
