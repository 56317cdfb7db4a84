"""The robot front end's first stage alone: how many labelled poles a candidate window covers, and how many windows a
frame sends to the crop network.

A pole is **covered** when a window holds at least 70 % of its box, and **framed** when, besides, the pole fills 30
to 130 % of the window's height (a pole cut by the frame's top or bottom may fill less): the windows the crop network
is trained on (``detector.crops.samples.pole_for``). Sets: the fresh rendered sets of ``bench_robot_table.py``
(back-lit poles only among them), each frame with its camera pose (and without it); and
``../shared/real-poles`` (no pose recorded). Recall is also given for poles under 16 px wide (at 640 px).
Usage: python benchmarks/bench_candidates.py [--sets FOLDER]
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

os.environ.setdefault("YOLO_OFFLINE", "true")
REPOSITORY = Path(__file__).resolve().parents[1]
SHARED = REPOSITORY.parent / "shared"
def candidate_recall(root: Path, use_pose: bool) -> dict:
    """Covered and framed poles (all, and under 16 px), candidates per frame and ms per frame over a dataset."""
    import cv2

    from detector.crops.samples import coverage, ground_view, label_boxes, pole_for
    from detector.datasets.io import load_dataset
    from detector.datasets.truth import load_camera_poses
    from naoslam.perception.candidates import CandidateFinder

    dataset = load_dataset(root)
    finder, poses = CandidateFinder(), load_camera_poses(dataset)
    counts = {"poles": 0, "covered": 0, "framed": 0, "small": 0, "small_covered": 0, "small_framed": 0}
    per_frame, seconds = [], 0.0
    for sample in dataset.samples:
        if sample.image is None:
            continue
        frame = cv2.imread(str(sample.image))
        height, width = frame.shape[:2]
        view = ground_view(poses.get(sample.image.name), (height, width)) if use_pose else None
        start = time.perf_counter()
        found = finder(frame, view)
        seconds += time.perf_counter() - start
        per_frame.append(len(found))
        boxes = label_boxes(sample, width, height)
        for index, box in enumerate(boxes):
            covered = any(coverage(c.window, box) >= 0.7 for c in found)
            framed = any(pole_for(c.window, boxes, (height, width)) == index for c in found)
            small = (box[2] - box[0]) * 640 / width < 16
            for key, hit in (("poles", True), ("covered", covered), ("framed", framed)):
                counts[key] += hit
                if small:
                    counts[{"poles": "small"}.get(key, f"small_{key}")] += hit
    return {**counts, "candidates": float(np.mean(per_frame)), "ms": 1000 * seconds / len(per_frame)}


def _share(hit: int, total: int) -> str:
    return f"{100 * hit / total:.1f} %" if total else "-"


def main() -> None:
    sys.path.insert(0, str(Path(__file__).parent))
    sys.path.insert(0, str(REPOSITORY))
    from bench_robot_table import fresh_sets

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sets", type=Path, default=REPOSITORY / "runs" / "robot-table")
    parser.add_argument("--frames", type=int, default=400)
    args = parser.parse_args()
    sets = fresh_sets(args.sets, args.frames)
    rows = [(f"{name}, {'with' if pose else 'without'} pose", candidate_recall(folder, pose))
            for name, folder in sets.items() for pose in (True, False)]
    if (SHARED / "real-poles" / "data.yaml").is_file():
        rows.append(("real-poles (no pose)", candidate_recall(SHARED / "real-poles", False)))
    print("| set | poles | covered | framed | under 16 px: covered / framed | candidates / frame | ms / frame |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for name, row in rows:
        print(f"| {name} | {row['poles']} | {_share(row['covered'], row['poles'])} | "
              f"{_share(row['framed'], row['poles'])} | {_share(row['small_covered'], row['small'])} / "
              f"{_share(row['small_framed'], row['small'])} of {row['small']} | {row['candidates']:.1f} | "
              f"{row['ms']:.2f} |")


if __name__ == "__main__":
    main()
