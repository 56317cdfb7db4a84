"""Second-look crops: the windows the robot's front end looks at a second time, cut where a trained crop network's
first look puts them, so the network learns the crops it meets there (clutter re-centred on its own box as well as
poles at their own scale) and not only the finder's windows and jittered ones around labelled poles."""
from __future__ import annotations

import numpy as np

from detector.crops.samples import CropSet, annotated_frames, crops_at, frame_candidates, label_boxes, labelled_windows
from detector.datasets.model import Dataset
from naoslam.perception.two_stage import CropDetector


def second_look_crops(detector: CropDetector, datasets: list[Dataset], split: str, progress: bool = True) -> CropSet:
    """For every frame of ``split`` of every dataset: the detector's first look at each candidate (with the pose
    and without it, as the training crops), the window of every second look it would take, each named by the pole
    it frames or as no pole (windows that frame neither clearly are left out)."""
    sets = []
    for dataset in datasets:
        for sample, frame, view in annotated_frames(dataset, (split,), "second looks in", progress):
            candidates = frame_candidates(frame, view, detector.finder)
            if not candidates:
                continue
            frame_hw = frame.shape[:2]
            out, boxes, windows = detector.first_look(frame, np.array([c.window for c in candidates]))
            _, again = detector.second_look_windows(out, boxes, windows, frame_hw)
            boxes = label_boxes(sample, frame_hw[1], frame_hw[0])
            kept, targets = labelled_windows([tuple(w) for w in again], boxes, frame_hw)
            sets.append(crops_at(frame, kept, targets, boxes, [i.cls for i in sample.instances], detector.size_wh))
    return CropSet.concatenate(sets) if sets else CropSet.empty(detector.size_wh)

