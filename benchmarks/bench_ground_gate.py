"""The ground-plane gate on frames full of look-alikes: false positives per frame with and without it, the real poles
it costs, and its time per frame against the front end without it.

Frames: ray-cast scenes with up to ten distractors each (banded tubes, tape, coloured paper, posters, goal posts) and
fewer poles than usual, camera pose from the renderer. Front end: the shipped model, at its own threshold and at
0.25 (where a weaker model would run). A detection is true when its mask overlaps a true pole of its class with
IoU >= 0.5.
Usage: python benchmarks/bench_ground_gate.py [FRAMES]
"""
from __future__ import annotations

import sys
import time

import cv2
import numpy as np

from detector.matching import greedy_match, mask_iou
from detector.synth.effects import apply_camera_effects, camera_effects
from detector.synth.render import render_scene
from detector.synth.scene import SceneConfig, sample_scene
from naoslam.camera import PinholeCamera
from naoslam.perception.yolo import LandmarkDetector

CROWDED = SceneConfig(max_distractors=10, max_poles=2, p_no_pole=0.3)


def crowded_frames(count: int, seed: int = 404):
    """(BGR frame, camera pose, true poles) of ``count`` look-alike-heavy scenes."""
    rng, effects, camera = np.random.default_rng(seed), camera_effects(), PinholeCamera()
    for _ in range(count):
        scene = sample_scene(rng, camera, CROWDED)
        frame = render_scene(scene)
        image = apply_camera_effects(effects, (frame.image * 255 + 0.5).astype(np.uint8), scene.effects_seed)
        yield cv2.cvtColor(image, cv2.COLOR_RGB2BGR), scene.pose, [p for p in frame.poles if p.mask.any()]


def count(detections, poles) -> tuple[int, int]:
    """(true, false) detections."""
    if not detections:
        return 0, 0
    iou = mask_iou([d.full_mask(poles[0].mask.shape) for d in detections], [p.mask for p in poles]) if poles else \
        np.zeros((len(detections), 0))
    allowed = np.array([[d.name == p.cls for p in poles] for d in detections]).reshape(iou.shape)
    true = len(greedy_match(iou, np.array([d.confidence for d in detections]), 0.5, allowed))
    return true, len(detections) - true


def main(frames: int) -> None:
    data = list(crowded_frames(frames))
    poles = sum(len(p) for _, _, p in data)
    for conf in (None, 0.25):
        detector = LandmarkDetector(conf=conf)
        totals = {"without": [0, 0, 0.0], "with": [0, 0, 0.0]}
        for image, pose, truth in data:
            for name, camera_pose in (("without", None), ("with", pose)):
                start = time.perf_counter()
                detections = detector(image, camera_pose)
                totals[name][2] += time.perf_counter() - start
                true, false = count(detections, truth)
                totals[name][0] += true
                totals[name][1] += false
        print(f"threshold {detector.conf:.2f}, {frames} frames, {poles} true poles:")
        for name, (true, false, seconds) in totals.items():
            print(f"  {name:7s} gate: {true:3d} true, {false:3d} false positives ({false / frames:.2f} per frame), "
                  f"{1000 * seconds / frames:.1f} ms per frame")
        ratio = totals["with"][1] / max(totals["without"][1], 1)
        print(f"  gate keeps {ratio:.2f} of the false positives and {totals['with'][0]}/{totals['without'][0]} true "
              f"detections; time with / without {totals['with'][2] / totals['without'][2]:.3f}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 150)
