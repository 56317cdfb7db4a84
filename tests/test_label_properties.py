"""Property tests (Hypothesis): valid outlines survive writing and reading, in label files and in COCO; corrupted
label lines are refused on their line, never read as something else."""
from __future__ import annotations

import json

import cv2
import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from detector.datasets.coco import load_coco
from detector.datasets.io import DatasetWriter, load_dataset
from detector.datasets.labels import parse_label_file
from detector.datasets.model import Instance
from detector.datasets.polygons import polygon_area
from naoslam.landmarks import CLASSES

SIZE = (64, 48)


@st.composite
def _star_outlines(draw) -> np.ndarray:
    """A convex-ish outline: 3-10 points around a centre, well inside the image (a few points may nearly line up)."""
    n = draw(st.integers(3, 10))
    cx, cy = draw(st.floats(0.25, 0.75)), draw(st.floats(0.25, 0.75))
    radii = draw(st.lists(st.floats(0.05, 0.2), min_size=n, max_size=n))
    angles = np.sort(draw(st.lists(st.floats(0, 2 * np.pi), min_size=n, max_size=n, unique=True)))
    points = np.stack([cx + np.array(radii) * np.cos(angles), cy + np.array(radii) * np.sin(angles)], axis=1)
    return points.clip(0, 1)


#: Outlines with a real area: the label check rightly refuses a polygon whose points (nearly) line up.
outlines = _star_outlines().filter(lambda polygon: polygon_area(polygon) > 1e-4)
instances = st.lists(st.tuples(st.sampled_from(CLASSES), outlines), min_size=0, max_size=4)
EXAMPLES = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


def _image() -> bytes:
    return cv2.imencode(".png", np.full((SIZE[1], SIZE[0], 3), 128, np.uint8))[1].tobytes()


@EXAMPLES
@given(items=instances)
def test_label_files_round_trip(items, tmp_path_factory):
    out = tmp_path_factory.mktemp("yolo") / "data"
    with DatasetWriter(out) as writer:
        writer.add("train", "frame.png", _image(), [Instance(c, p) for c, p in items])
    read = load_dataset(out).split("train")[0].instances
    assert [i.cls for i in read] == [c for c, _ in items]
    for instance, (_, polygon) in zip(read, items):
        assert np.abs(instance.polygon - polygon).max() < 1e-6


@EXAMPLES
@given(items=instances)
def test_coco_round_trips(items, tmp_path_factory):
    root = tmp_path_factory.mktemp("coco")
    (root / "train").mkdir()
    (root / "train" / "frame.png").write_bytes(_image())
    size = np.array(SIZE, float)
    coco = {"images": [{"id": 7, "file_name": "frame.png", "width": SIZE[0], "height": SIZE[1]}],
            "categories": [{"id": i + 1, "name": c} for i, c in enumerate(CLASSES)],
            "annotations": [{"id": k, "image_id": 7, "category_id": CLASSES.index(c) + 1,
                             "segmentation": [(p * size).reshape(-1).tolist()]} for k, (c, p) in enumerate(items)]}
    (root / "train" / "_annotations.coco.json").write_text(json.dumps(coco))
    dataset = load_coco(root)
    assert not dataset.errors
    read = dataset.samples[0].instances
    assert [i.cls for i in read] == [c for c, _ in items]
    for instance, (_, polygon) in zip(read, items):
        assert np.abs(instance.polygon - polygon).max() < 1e-9


CORRUPTIONS = {
    "a word for a number": lambda tokens, rng: tokens[:1] + ["x" + tokens[1]] + tokens[2:],
    "one number dropped": lambda tokens, rng: tokens[:-1],
    "nan coordinate": lambda tokens, rng: tokens[:2] + ["nan"] + tokens[3:],
    "inf class": lambda tokens, rng: ["inf"] + tokens[1:],
    "class out of range": lambda tokens, rng: [str(len(CLASSES) + int(rng.integers(0, 50)))] + tokens[1:],
    "fractional class": lambda tokens, rng: ["1.5"] + tokens[1:],
    "pixels, not fractions": lambda tokens, rng: tokens[:1] + [str(float(t) * 640) for t in tokens[1:]],
}


@EXAMPLES
@given(polygon=outlines, cls=st.sampled_from(CLASSES), kind=st.sampled_from(sorted(CORRUPTIONS)),
       seed=st.integers(0, 2**16), line_no=st.integers(0, 3))
def test_corrupted_lines_are_refused_on_their_line(polygon, cls, kind, seed, line_no, tmp_path_factory):
    good = f"{CLASSES.index(cls)} " + " ".join(f"{v:.6f}" for v in polygon.reshape(-1))
    bad = " ".join(CORRUPTIONS[kind](good.split(), np.random.default_rng(seed)))
    lines = [good] * line_no + [bad] + [good]
    label = tmp_path_factory.mktemp("labels") / "frame.txt"
    label.write_text("\n".join(lines) + "\n")
    read, problems = parse_label_file(label, CLASSES)
    assert [p.line for p in problems if p.severity == "error"] == [line_no + 1]
    assert len(read) == line_no + 1 and all(i.cls == cls for i in read)
