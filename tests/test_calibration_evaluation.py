"""Range calibration, the measurement model, per-image counting and the colour-filter baseline."""
from __future__ import annotations

import json
import math
import re
import shutil
from dataclasses import replace

import cv2
import numpy as np
import pytest

from detector.formats import read_record
from calibration.fit import WALK_RELATIVE_STD, calibrate, fit_power_law
from calibration.report import CalibrationReport
from detector.model_files import load_calibration
from calibration.samples import measure_samples, open_ranged
from detector.cli import main
from detector.datasets import load_dataset
from detector.outputs import OUTPUT_MARKER
from detector.datasets.truth import load_truth
from detector.evaluation.by_width import label_width_px, recall_by_width, width_bin_names
from detector.evaluation.counting import (best_threshold, confusion_matrix, evaluate_image, outcome,
                                          totals)
from detector.evaluation.predictors import RuntimePredictor
from detector.evaluation.results import Counts, Evaluation, SweepPoint
from detector.evaluation.run import evaluate
from detector.synth.generate import SynthJob, generate_dataset
from detector.synth.render import render_scene
from detector.synth.scene import calibration_scene
from naoslam.camera import PinholeCamera
from naoslam.perception.colour_filter import ColourFilter
from naoslam.perception.detections import Detection
from naoslam.perception.yolo import LandmarkDetector
from naoslam.landmarks import CLASSES, PoleGeometry
from naoslam.shipped import DEFAULT_CONF
from naoslam.measurement import MeasurementModel, PowerLaw, RangeCalibration, on_axis_size


@pytest.fixture(scope="module")
def calibration_shots(tmp_path_factory):
    """The renderer's calibration shots: every class at 0.5-5 m and 0, +-10, +-20 deg (640x480)."""
    return generate_dataset(tmp_path_factory.mktemp("calib") / "shots", SynthJob(90, seed=4, calibration_shots=True),
                            workers=2, progress=False)


def test_fit_recovers_a_known_power_law():
    px = np.geomspace(10, 300, 40)
    law, r2 = fit_power_law(px, 55.0 * px ** -0.98)
    assert law.a == pytest.approx(55.0, rel=1e-9) and law.b == pytest.approx(-0.98, abs=1e-12) and r2 == pytest.approx(1)


def test_calibration_shots_recover_the_camera_law(calibration_shots):
    calibration, report = calibrate(measure_samples(open_ranged(calibration_shots, progress=False), progress=False))
    # A pinhole camera makes pixel size inversely proportional to range: exponents near -1.
    assert calibration.width_law.b == pytest.approx(-1.0, abs=0.06)
    assert calibration.height_law.b == pytest.approx(-1.0, abs=0.06)
    # Height law against the pinhole prediction: height_px = f * 0.42 m / range.
    focal = PinholeCamera().focal_px
    assert calibration.height_law(focal * 0.42 / 2.0) == pytest.approx(2.0, rel=0.05)
    far = [row for row in report.errors_by_range if float(row.label.split("-")[0]) >= 1.25]
    assert far and all(row.rule < 5.0 and row.fused < 5.0 for row in far)
    # The shots carry the camera pose: wherever the foot is in view, its row gives the range within 2 %.
    with_foot = [row for row in far if row.foot_samples]
    assert with_foot and all(row.foot < 2.0 and row.fused_foot <= row.fused + 0.5 for row in with_foot)
    assert report.colour.b == pytest.approx(-1.0, abs=0.06)
    assert math.degrees(calibration.bearing_std_rad) < 0.3
    # The laws are fitted on on-axis sizes, so poles shot at +-10 and +-20 deg fit them as tightly as those ahead;
    # the filter is still told the noise of a walking robot's frames, which still shots understate.
    assert calibration.off_axis_corrected
    # (the shots reach 9 m, where a pole is 7 px wide and half a pixel is 7 %, and the camera rolls up to 3 deg,
    # which widens a tilted pole's box by 0.5-1.5 px: the width law's residual is the wider)
    assert report.width.relative_std < 0.10 and report.height.relative_std < 0.03
    assert calibration.width_law.relative_std == WALK_RELATIVE_STD["width"]
    assert calibration.height_law.relative_std == WALK_RELATIVE_STD["height"]
    assert calibration.colour_law.relative_std == max(report.colour.relative_std, WALK_RELATIVE_STD["colour"])


def test_the_colour_law_is_fitted_on_what_the_colour_filter_measures(calibration_shots):
    """It was fitted on the renderer's exact band distances, which the filter reads about 4 % longer: every range it
    gave read short, and a team's own photographs (no band distances in their truth CSV) had no colour law at all."""
    ranged = open_ranged(calibration_shots, progress=False)
    samples = measure_samples(ranged, progress=False)
    colour_filter = ColourFilter()
    measured = [s for s in samples if s.band_distance_px is not None]
    assert len(measured) > len(samples) / 2
    for sample in measured[:10]:
        frame = cv2.imread(str(calibration_shots / "train" / "images" / sample.image))
        if frame is None:
            frame = next(cv2.imread(str(p)) for p in calibration_shots.rglob(sample.image))
        assert sample.band_distance_px in [d.band_distance_px for d in colour_filter(frame)]
    calibration, _ = calibrate(samples)
    errors = np.array([calibration.colour_range(s.band_distance_px, s.image_width, column=s.centre_column)[0]
                       / s.range_m - 1 for s in measured])
    assert abs(float(np.median(errors))) < 0.01
    # Its band distances are taken to the optical axis as the box sizes are: a pole shot at 20 deg reads as far
    # as one straight ahead. Fitted on raw distances, the law read the poles ahead 3 % long and those at 20 deg
    # 3 % short.
    assert calibration.colour_off_axis_corrected
    bearings = np.degrees(np.abs([s.bearing_rad for s in measured]))
    for ahead_or_aside in (bearings < 5, bearings > 15):
        assert ahead_or_aside.sum() >= 5 and abs(float(np.median(errors[ahead_or_aside]))) < 0.015


def test_a_walks_sightings_set_the_noise_the_filter_is_told(calibration_shots):
    shots = measure_samples(open_ranged(calibration_shots, progress=False), progress=False)
    plain, _ = calibrate(shots)
    rng = np.random.default_rng(0)
    # A walk whose masks read 15 % off in width and 4 % in height (s.d.), and whose band distances the colour
    # filter reads 10 % off, where the still shots read 1-4 %.
    walk = [replace(s, width_px=s.width_px * math.exp(rng.normal(0, 0.15)),
                    height_px=s.height_px * math.exp(rng.normal(0, 0.04)),
                    band_distance_px=s.band_distance_px and s.band_distance_px * math.exp(rng.normal(0, 0.10)))
            for s in shots for _ in range(4)]
    calibration, report = calibrate(shots, walk_samples=walk)
    assert calibration.width_law.relative_std == pytest.approx(0.15, rel=0.15)
    assert calibration.height_law.relative_std == pytest.approx(0.04, rel=0.15)
    assert calibration.colour_law.relative_std == pytest.approx(0.10, rel=0.15)
    assert report.colour.walk.sightings == 4 * sum(s.band_distance_px is not None for s in shots)
    assert report.height.walk.sightings == 4 * sum(not s.partial for s in shots)
    # The walk sets the noise only: the laws are the still shots'.
    assert (calibration.width_law.a, calibration.height_law.b) == (plain.width_law.a, plain.height_law.b)
    # A walk that reads as well as the shots tells the filter the fit's own residual, not the default floor.
    steady, report = calibrate(shots, walk_samples=shots)
    assert steady.height_law.relative_std == pytest.approx(report.height.relative_std, rel=0.5)
    assert steady.height_law.relative_std < WALK_RELATIVE_STD["height"]
    with pytest.raises(ValueError, match="--noise-data: 5 sightings measure the width law"):
        calibrate(shots, walk_samples=shots[:5])


def test_calibrate_measures_the_noise_on_a_rendered_walk(calibration_shots, tmp_path, capsys):
    walk = generate_dataset(tmp_path / "walk", SynthJob(30, seed=1, walk="square"), workers=2, progress=False)
    out, plot = tmp_path / "calibration.json", tmp_path / "fit.png"
    assert main(["calibrate", "--data", str(calibration_shots), "--noise-data", str(walk), "--out", str(out),
                 "--plot", str(plot)]) == 0
    assert cv2.imread(str(plot)) is not None
    report = CalibrationReport.from_json(json.loads(out.read_text())["report"])
    labelled = sum(len(i["landmarks"]) for i in json.loads((walk / "annotations.json").read_text())["images"].values())
    assert report.width.walk.sightings == labelled >= 20
    # 30 frames hold too few poles the colour filter reads to measure its noise: its default is kept, and said.
    assert report.colour.walk_too_few < 20 and report.colour.walk is None
    assert load_calibration(out).colour_law.relative_std == max(report.colour.relative_std,
                                                                WALK_RELATIVE_STD["colour"])
    assert report.noise_source == str(walk) and f"measured on {walk}" in capsys.readouterr().out.replace("\n", "")
    assert load_calibration(out).width_law.relative_std == max(report.width.relative_std,
                                                               report.width.walk.relative_std)


def test_noise_data_without_true_ranges_is_refused_before_anything_is_measured(calibration_shots, dataset_copy,
                                                                            tmp_path, capsys):
    (dataset_copy / "annotations.json").unlink()  # a plain Roboflow export: masks, no ranges
    out = tmp_path / "calibration.json"
    assert main(["calibrate", "--data", str(calibration_shots), "--noise-data", str(dataset_copy),
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"{dataset_copy}: no landmark has a true range" in err and "Traceback" not in err and not out.exists()
    assert "measuring" not in err  # refused before the shots were measured


def test_the_minimal_annotations_json_a_team_writes_gives_the_same_sizes_and_ranges(synth_dataset, dataset_copy):
    """docs/range-calibration.md: each image's landmarks as {cls, range_m}, in its label file's order, and the
    camera's pose, which takes the sizes to a level camera's."""
    full = json.loads((synth_dataset / "annotations.json").read_text())["images"]
    minimal = {"images": {name: {"landmarks": [{"cls": lm["cls"], "range_m": lm["range_m"]}
                                               for lm in entry["landmarks"]],
                                 "camera": {key: entry["camera"][key] for key in ("height_m", "pitch_rad", "roll_rad")}}
                          for name, entry in full.items()}}
    (dataset_copy / "annotations.json").write_text(json.dumps(minimal))
    expected = measure_samples(open_ranged(synth_dataset, progress=False), progress=False)
    written = measure_samples(open_ranged(dataset_copy, progress=False), progress=False)
    assert len(written) == len(expected) >= 10
    assert [(s.image, s.cls, s.range_m, s.width_px, s.height_px) for s in written] == \
        [(s.image, s.cls, s.range_m, s.width_px, s.height_px) for s in expected]


@pytest.mark.parametrize("bearing_deg", [0.0, 12.0, -20.0, 28.0])
def test_on_axis_size_undoes_the_pinhole_stretch_of_a_pole_to_the_side(bearing_deg):
    camera = PinholeCamera(640, 480, 56.3)
    range_m, diameter_m, height_m = 3.0, 0.11, 0.42
    bearing = math.radians(bearing_deg)
    half = math.asin(diameter_m / 2 / range_m)
    # The pole's silhouette edges and its centre, projected exactly; its image height from its depth.
    left, right = (camera.cx - camera.focal_px * math.tan(bearing + s * half) for s in (1, -1))
    width = right - left
    height = camera.focal_px * height_m / (range_m * math.cos(bearing))
    centre = camera.cx - camera.focal_px * math.tan(bearing)
    on_axis_width, on_axis_height = on_axis_size(width, height, centre, 640, 56.3)
    assert on_axis_width == pytest.approx(2 * camera.focal_px * math.tan(half), rel=2e-3)
    assert on_axis_height == pytest.approx(camera.focal_px * height_m / range_m, rel=1e-9)


def test_range_undoes_the_off_axis_stretch_only_for_a_calibration_fitted_so():
    laws = PowerLaw(50.0, -1.0, 0.04), PowerLaw(220.0, -1.0, 0.01)
    corrected, legacy = RangeCalibration(*laws, off_axis_corrected=True), RangeCalibration(*laws)
    edge = 10.0  # a pole near the left border of a 640 px frame, 2 m away: 25 x 110 px on the axis
    cos_t = math.cos(math.atan((320 - edge) / PinholeCamera(640, 480, 56.3).focal_px))
    width, height = 25 / cos_t ** 2, 110 / cos_t
    assert corrected.range_from_box(width, height, 640, column=edge)[0] == pytest.approx(2.0, rel=1e-6)
    # Calibrations from before the correction were fitted on raw sizes: the column changes nothing for them.
    assert legacy.range_from_box(width, height, 640, column=edge) == legacy.range_from_box(width, height, 640)
    assert legacy.range_from_box(width, height, 640)[0] < 1.8
    assert RangeCalibration.from_dict(legacy.to_dict()) == legacy
    assert RangeCalibration.from_dict(corrected.to_dict()).off_axis_corrected


def test_colour_range_undoes_the_off_axis_stretch_only_for_a_colour_law_fitted_so():
    """The distance between a pole's bands is a vertical length: at bearing t it shows 1 / cos t longer."""
    laws = PowerLaw(50.0, -1.0, 0.04), PowerLaw(220.0, -1.0, 0.01)
    colour_law = PowerLaw(5.9, -1.0, 0.05)  # range = 5.9 / (px per cm of band spacing)
    corrected = RangeCalibration(*laws, colour_law=colour_law, off_axis_corrected=True, colour_off_axis_corrected=True)
    legacy = RangeCalibration(*laws, colour_law=colour_law, off_axis_corrected=True)
    edge = 10.0
    cos_t = math.cos(math.atan((320 - edge) / PinholeCamera(640, 480, 56.3).focal_px))
    on_axis = 5.9 / 2.0 * PoleGeometry().band_height * 100  # px between the band centres at 2 m, ahead
    assert corrected.colour_range(on_axis / cos_t, 640, column=edge)[0] == pytest.approx(2.0, rel=1e-6)
    assert corrected.colour_range(on_axis, 640, column=320.0)[0] == pytest.approx(2.0, rel=1e-6)
    assert legacy.colour_range(on_axis / cos_t, 640, column=edge) == legacy.colour_range(on_axis / cos_t, 640)
    assert RangeCalibration.from_dict(corrected.to_dict()) == corrected


def test_range_rule_uses_width_for_a_cut_pole_and_scales_with_resolution():
    calibration = RangeCalibration(PowerLaw(50.0, -1.0, 0.06), PowerLaw(220.0, -1.0, 0.03), upright_ratio=0.21)
    # Whole pole at 2 m: width 25 px, height 110 px; both laws agree and fusion leans on the better height law.
    fused, fused_std, used = calibration.range_from_box(25, 110, 640)
    assert used == "fused" and fused == pytest.approx(2.0, rel=1e-6) and fused_std < 0.03 * 2.0
    # The same pole with its base cut off by the image border: too wide for its height, so the width decides.
    assert calibration.range_from_box(25, 60, 640, "rule")[0:3:2] == (pytest.approx(2.0), "width")
    # A 1280 px frame sees everything twice as large; normalised to the reference width it is the same range.
    assert calibration.range_from_box(50, 220, 1280)[0] == pytest.approx(fused)
    with pytest.raises(ValueError, match="not one of"):
        calibration.range_from_box(25, 110, 640, "median")


def test_a_model_without_calibration_is_refused_when_the_measurement_model_is_built(tiny_onnx):
    """The robot's pattern ``MeasurementModel(detector.calibration)`` with a model that carries none used to fail
    at the first detection with an AttributeError on None."""
    from naoslam.perception.yolo import LandmarkDetector

    detector = LandmarkDetector(tiny_onnx)
    assert detector.calibration is None
    with pytest.raises(TypeError, match=r"not NoneType .* - fix: `poles calibrate --model MODEL.onnx --embed"):
        MeasurementModel(detector.calibration, min_confidence=detector.conf)


def test_a_broken_calibration_in_a_model_is_refused_naming_the_model(tiny_onnx, tmp_path):
    """A range law with a <= 0 in a model's metadata gave nonsense ranges; with the law's own check it would name
    no file."""
    from detector.model_files import add_metadata

    model = tmp_path / "model.onnx"
    shutil.copy(tiny_onnx, model)
    broken = RangeCalibration(PowerLaw(50.0, -1.0), PowerLaw(220.0, -1.0)).to_dict()
    broken["width_law"]["a"] = -50.0
    add_metadata(model, calibration=broken)
    with pytest.raises(ValueError, match=r"model.onnx: the calibration in the model is not one .* a must be above 0"):
        LandmarkDetector(model).calibration


def test_measurement_model_keeps_confident_detections_only(tiny_onnx, synth_dataset):
    from naoslam.perception.yolo import LandmarkDetector

    calibration = RangeCalibration(PowerLaw(50.0, -1.0), PowerLaw(220.0, -1.0))
    frame = cv2.imread(str(sorted((synth_dataset / "test" / "images").glob("*.jpg"))[0]))
    detections = LandmarkDetector(tiny_onnx, conf=0.001)(frame)
    threshold = float(np.median([d.confidence for d in detections]))
    measurements = MeasurementModel(calibration, min_confidence=threshold).measure(detections, frame.shape[1])
    assert 0 < len(measurements) < len(detections)
    for m in measurements:
        assert m.confidence >= threshold and m.range_m > 0 and m.range_std > 0
        assert abs(m.bearing_rad) <= math.radians(56.3 / 2) + 1e-9 and m.signature in CLASSES


def test_calibrate_command_writes_json_plot_and_embeds_in_every_model_named(calibration_shots, tiny_onnx, tmp_path,
                                                                             capsys):
    model, int8 = tmp_path / "model.onnx", tmp_path / "model-int8.onnx"  # as `poles export --int8` names them
    for path in (model, int8):
        path.write_bytes(tiny_onnx.read_bytes())
    out, plot = tmp_path / "calibration.json", tmp_path / "fit.png"
    argv = ["calibrate", "--data", str(calibration_shots), "--out", str(out), "--plot", str(plot), "--force"]
    assert main(argv + ["--embed", str(model)]) == 0
    assert f"note: {int8}, its INT8 copy, was not given this calibration: add --embed {int8}" in capsys.readouterr().out
    assert cv2.imread(str(plot)) is not None
    calibration = load_calibration(out)
    assert RuntimePredictor(model).calibration == calibration and RuntimePredictor(int8).calibration is None
    assert main(argv + ["--embed", str(model), "--embed", str(int8)]) == 0
    assert "note:" not in capsys.readouterr().out
    assert RuntimePredictor(model).calibration == RuntimePredictor(int8).calibration == load_calibration(out)
    assert main(["calibrate", "--data", str(calibration_shots), "--out", str(out)]) == 2  # exists, no --force


def test_truth_csv_errors_name_file_and_line(synth_dataset, tmp_path):
    dataset = load_dataset(synth_dataset)
    sample = next(s for s in dataset.samples if len({i.cls for i in s.instances}) == len(s.instances) > 0)
    good = tmp_path / "truth.csv"
    good.write_text(f"image,class,range_m\n{sample.image.name},{sample.instances[0].cls},2.5\n")
    assert load_truth(dataset, good)[sample.image.name][0]["range_m"] == 2.5
    bad = tmp_path / "bad.csv"
    bad.write_text(f"image,class,range_m\n{sample.image.name},{sample.instances[0].cls},far\n")
    with pytest.raises(ValueError, match=r"bad.csv:2: range_m 'far' is not a number"):
        load_truth(dataset, bad)


def _rectangle(x0, width=10, height=40, shape=(100, 100)):
    mask = np.zeros(shape, bool)
    mask[20:20 + height, x0:x0 + width] = True
    return mask


def _evaluate(name, truth_classes, truth_masks, classes, masks, scores=None):
    """``evaluate_image`` of detections of ``classes`` with ``masks`` (full frame) and ``scores`` (default 0.9)."""
    detections = [Detection.from_mask(c, s, m) for c, s, m in zip(classes, scores or [0.9] * len(classes), masks)]
    shape = (truth_masks or masks or [np.zeros((100, 100), bool)])[0].shape
    return evaluate_image(name, truth_classes, truth_masks, [None] * len(truth_classes), detections, shape, "mask")


def test_perfect_predictions_score_one():
    masks = [_rectangle(10), _rectangle(50)]
    image = _evaluate("a.jpg", ["bp", "pg"], masks, ["bp", "pg"], masks)
    counts = totals([image], 0.5)
    assert counts == Counts(tp=2)
    assert counts.precision_recall()[:2] == (1.0, 1.0)
    assert [image.overlap[p, r] for p, r in image.match(0.5)] == [1.0, 1.0]


def test_shifted_masks_give_the_hand_computed_iou():
    truth = [_rectangle(10)]
    # Shifted 2 px: intersection 8x40, union 12x40 -> IoU 2/3, still a true positive.
    near = _evaluate("a.jpg", ["py"], truth, ["py"], [_rectangle(12)])
    assert near.overlap[0, 0] == pytest.approx(2 / 3) and near.counts(0.5).tp == 1
    # Shifted 6 px: 4x40 over 16x40 -> 0.25: one false positive and one false negative.
    far = _evaluate("a.jpg", ["py"], truth, ["py"], [_rectangle(16)])
    assert far.overlap[0, 0] == pytest.approx(0.25) and far.counts(0.5) == Counts(fp=1, fn=1)
    # Right place, wrong class: not a match.
    wrong = _evaluate("a.jpg", ["py"], truth, ["yp"], truth)
    assert wrong.counts(0.5) == Counts(fp=1, fn=1)
    # Below the threshold a detection does not count at all.
    low = _evaluate("a.jpg", ["py"], truth, ["py"], truth, [0.3])
    assert low.counts(0.5) == Counts(fn=1)


def test_recall_by_width_puts_each_label_in_the_bin_of_its_width():
    widths = [6, 12, 40, 100]
    shape = (200, 640)
    masks = [_rectangle(10 + 150 * i, width=w, height=120, shape=shape) for i, w in enumerate(widths)]
    found = [masks[1], masks[3]]
    image = _evaluate("a.jpg", ["bp"] * 4, masks, ["bp", "bp"], found)
    rows = recall_by_width([image], 0.5)
    assert [row.width for row in rows] == width_bin_names() == ["< 10 px", "10-16 px", "16-32 px", "32-64 px",
                                                                   ">= 64 px"]
    assert [(row.labels, row.found) for row in rows] == [(1, 0), (1, 1), (0, 0), (1, 0), (1, 1)]
    assert [row.recall for row in rows] == [0.0, 1.0, None, 0.0, 1.0]
    assert sum(row.found for row in rows) == totals([image], 0.5).tp


def test_label_width_is_measured_across_a_tilted_pole_and_scaled_to_a_640_px_frame():
    upright = _rectangle(100, width=24, height=200, shape=(400, 1280))
    assert label_width_px(upright) == pytest.approx(12, abs=0.6)
    tilted = np.zeros((480, 640), np.uint8)
    cv2.fillPoly(tilted, [cv2.boxPoints(((320, 240), (10, 120), 20)).astype(np.int32)], 1)
    assert 9 < label_width_px(tilted.astype(bool)) < 13  # rasterised 10 px; the upright box would be 50 px wide


def test_empty_images_without_detections_are_true_negatives():
    images = [_evaluate(f"{i}.jpg", [], [], [], []) for i in range(5)]
    assert totals(images, 0.5) == Counts(tn=5)


def test_confusion_matrix_separates_swaps_duplicates_and_misses():
    left, middle, right = _rectangle(10), _rectangle(50), _rectangle(90)
    image = _evaluate("a.jpg", ["bp", "pg", "py"], [left, middle, right], ["bp", "gp", "pb", "yp"],
                      [left, left, middle, _rectangle(70)], [0.9, 0.8, 0.7, 0.6])
    result = outcome(image, 0.5)
    assert (result.matches, result.swaps, result.duplicates, result.strays, result.missed) == \
        ([(0, 0)], [(2, 1)], [1], [3], [2])
    matrix = confusion_matrix([image], [result], CLASSES)
    bp, gp, yp, pb, pg, py, none = range(7)
    expected = np.zeros((7, 7), dtype=int)
    expected[bp, bp] = 1  # the true positive
    expected[pg, pb] = 1  # right place, wrong class: a swap
    expected[none, gp] = 1  # a second box on the matched bp: a false positive on no free label
    expected[none, yp] = 1  # nothing there
    expected[py, none] = 1  # missed
    assert (matrix == expected).all()
    counts = image.counts(0.5)
    assert counts.fp == matrix[:, :6].sum() - np.trace(matrix) and counts.fn == matrix[:6].sum() - np.trace(matrix)


def _clean_pole_frame(code: str, range_m: float, angle_deg: float = 0.0) -> np.ndarray:
    scene = calibration_scene(np.random.default_rng(2), PinholeCamera(), code, range_m, angle_deg)
    return cv2.cvtColor((render_scene(scene).image * 255).astype(np.uint8), cv2.COLOR_RGB2BGR)


@pytest.mark.parametrize("code", CLASSES)
def test_colour_filter_finds_poles_in_clean_frames(code):
    found = ColourFilter()(_clean_pole_frame(code, 1.5, 10.0))
    assert code in [d.name for d in found]
    hit = next(d for d in found if d.name == code)
    # The pole stands 10 deg to the left: the band-dividing point lies left of centre, near that bearing.
    bearing = math.degrees(float(PinholeCamera().bearing_of_column(hit.centre_column)))
    assert bearing == pytest.approx(10.0, abs=1.0)


def test_colour_filter_rejects_a_pink_poster_without_a_second_band():
    frame = np.full((480, 640, 3), (235, 235, 235), np.uint8)  # white wall
    frame[150:260, 300:360] = (160, 70, 235)  # pink poster (BGR)
    assert ColourFilter()(frame) == []
    frame[260:370, 300:360] = (230, 166, 64)  # a blue band under it, but nothing white below: still no landmark
    frame[370:, :] = (40, 120, 40)
    assert ColourFilter()(frame) == []


def test_evaluate_keeps_a_used_out_and_force_replaces_it_whole(synth_dataset, tmp_path, capsys):
    out = tmp_path / "eval"
    (out / "errors").mkdir(parents=True)
    (out / "errors" / "old-model_fp.jpg").write_bytes(b"yesterday's overlay")
    (out / OUTPUT_MARKER).write_text(json.dumps({"written_by": "poles", "kind": "evaluation",
                                                 "files": ["errors/old-model_fp.jpg"]}))
    argv = ["evaluate", str(synth_dataset), "--model", "colour-filter", "--out", str(out)]
    assert main(argv) == 2
    assert "--force" in capsys.readouterr().err
    assert (out / "errors" / "old-model_fp.jpg").exists() and not (out / "metrics.json").exists()
    assert main([*argv, "--force"]) == 0
    assert not (out / "errors" / "old-model_fp.jpg").exists()  # no overlay of another run is left to mislead
    assert read_record(out / "metrics.json", "evaluation")["model"] == "colour-filter"


def test_evaluate_writes_metrics_plots_and_overlays(synth_dataset, tmp_path):
    metrics = evaluate(RuntimePredictor("colour-filter"), synth_dataset, tmp_path / "eval", progress=False)
    assert Evaluation.from_json(read_record(tmp_path / "eval" / "metrics.json", "evaluation")) == metrics
    test = load_dataset(synth_dataset).split("test")
    counts = metrics.counts
    assert metrics.images == len(test) == len(metrics.per_image) and metrics.bearing_error is not None
    assert counts.tp + counts.fn == sum(len(s.instances) for s in test)
    assert sum((row.counts for row in metrics.per_image), Counts()) == counts
    assert cv2.imread(str(tmp_path / "eval" / "per_image.png")) is not None
    assert cv2.imread(str(tmp_path / "eval" / "confusion.png")) is not None
    assert cv2.imread(str(tmp_path / "eval" / "recall_by_width.png")) is not None
    assert sum(row.labels for row in metrics.recall_by_width) == counts.tp + counts.fn
    assert sum(row.found for row in metrics.recall_by_width) == counts.tp
    confusion = np.array(metrics.confusion.counts)
    assert np.trace(confusion) == counts.tp and confusion[:-1].sum() == counts.tp + counts.fn
    assert len(list((tmp_path / "eval" / "errors").glob("*.jpg"))) == metrics.overlays


def test_real_poles_calibration_images_measure(real_poles):
    samples = measure_samples(open_ranged(real_poles, progress=False), progress=False)
    assert len(samples) == 6 and all(s.partial for s in samples) and all(s.image_width == 1280 for s in samples)


def test_evaluate_a_pytorch_checkpoint_like_its_onnx_export(tiny_weights, tiny_onnx, synth_dataset, tmp_path):
    from detector.evaluation.predictors import make_predictor

    torch_metrics = evaluate(make_predictor(str(tiny_weights), imgsz=128), synth_dataset, tmp_path / "pt",
                             conf=0.001, progress=False)
    onnx_metrics = evaluate(make_predictor(str(tiny_onnx)), synth_dataset, tmp_path / "onnx", conf=0.001,
                            progress=False)
    assert torch_metrics.images == onnx_metrics.images > 0
    found = [metrics.counts.tp + metrics.counts.fp for metrics in (torch_metrics, onnx_metrics)]
    assert abs(found[0] - found[1]) <= 2


def test_evaluate_takes_a_train_run_folder_for_its_best_checkpoint(tiny_run, tmp_path):
    from detector.evaluation.predictors import TorchPredictor, make_predictor

    predictor = make_predictor(str(tiny_run))
    assert isinstance(predictor, TorchPredictor) and predictor.name == "best.pt"
    with pytest.raises(ValueError, match="give a .pt checkpoint \\(or its run folder\\)"):
        make_predictor(str(tmp_path))  # a folder without weights/best.pt is not a run


def test_a_models_calibration_holds_only_at_the_input_width_it_was_measured_at(calibration_shots, tmp_path, capsys):
    """A model's masks change with its input width, so its calibration records the width and is refused at another."""
    from calibration.run import embed_calibration
    from naoslam.perception.yolo import LandmarkDetector
    from naoslam.shipped import shipped_model

    small = tmp_path / "calibration-320.json"
    assert main(["calibrate", str(calibration_shots), "--model", "shipped", "--imgsz", "320", "--out", str(small)]) == 0
    at_320, at_640 = load_calibration(small), LandmarkDetector().calibration
    assert (at_320.input_width, at_640.input_width) == (320, 640)
    assert abs(at_320.width_law(20.0) / at_640.width_law(20.0) - 1) > 0.02  # the smaller input's masks read wider
    assert LandmarkDetector(input_width=320).check_calibration(at_320) is at_320
    with pytest.raises(ValueError, match=r"measured at 320 px input, the model runs at 640 px here.*--imgsz 640"):
        LandmarkDetector().check_calibration(at_320)

    model = tmp_path / "poles.onnx"
    model.write_bytes(shipped_model().read_bytes())
    embed_calibration(model, at_320)
    with pytest.raises(ValueError, match="measured at 320 px input"):
        LandmarkDetector(model).calibration  # noqa: B018 - the property refuses to hand it out at 640
    assert LandmarkDetector(model, input_width=320).calibration == at_320

    def evaluate_at_320(*calibration: str) -> int:
        return main(["evaluate", str(calibration_shots), "--imgsz", "320", *calibration, "--out",
                     str(tmp_path / f"eval{len(calibration)}")])

    assert evaluate_at_320("--calibration", str(small)) == 0
    assert read_record(tmp_path / "eval2" / "metrics.json", "evaluation")["range_error"]["median"] < 0.1
    assert evaluate_at_320() == 0  # the shipped calibration is the 640 px one: no range figures rather than wrong ones
    assert read_record(tmp_path / "eval0" / "metrics.json", "evaluation")["range_error"] is None
    capsys.readouterr()
    assert main(["slam", "--sim", "square", "--frontend", "shipped", "--imgsz", "320", "--duration", "5",
                 "--out", str(tmp_path / "slam")]) == 2
    assert "measured at 640 px input, the model runs at 320 px" in capsys.readouterr().err
    assert main(["calibrate", str(calibration_shots), "--imgsz", "320", "--out", str(tmp_path / "labels.json")]) == 2
    assert "--imgsz is a model's input width" in capsys.readouterr().err


def test_evaluate_keeps_models_of_the_same_file_name_apart(synth_dataset, tiny_onnx, tmp_path, capsys):
    """`runs/a/best.onnx` against `runs/b/best.onnx` wrote both into one folder, the second over the first."""
    for run in ("a", "b"):
        (tmp_path / run).mkdir()
        shutil.copyfile(tiny_onnx, tmp_path / run / "best.onnx")
    out = tmp_path / "eval"
    assert main(["evaluate", str(synth_dataset), "--model", str(tmp_path / "a" / "best.onnx"), "--model",
                 str(tmp_path / "b" / "best.onnx"), "--model", "colour-filter", "--model", "colour-filter",
                 "--out", str(out)]) == 0
    folders = sorted(p.name for p in out.iterdir() if p.is_dir())
    assert folders == ["a_best.onnx", "b_best.onnx", "colour-filter", "colour-filter-2"]
    assert [read_record(out / f / "metrics.json", "evaluation")["model"] for f in folders] == folders


def test_evaluate_prints_each_models_own_threshold(synth_dataset, tiny_onnx, tmp_path, capsys):
    """The table's title once gave the first model's threshold for every column; the shipped model counts at 0.65."""
    assert main(["evaluate", str(synth_dataset), "--model", str(tiny_onnx), "--model", "shipped",
                 "--out", str(tmp_path / "eval")]) == 0
    printed = capsys.readouterr().out.splitlines()
    row = next(line for line in printed if "threshold (the counts')" in line)
    assert re.findall(r"\d\.\d\d", row) == [f"{DEFAULT_CONF:.2f}", f"{LandmarkDetector().stored_conf:.2f}"]
    # The second column against the first, on the same frames, with its spread over them.
    f1 = [read_record(tmp_path / "eval" / name / "metrics.json", "evaluation")["f1"]
          for name in (tiny_onnx.name, "poles-yolov8n-seg.onnx")]
    versus = next(line for line in printed if "F1 - the first's" in line)
    difference, low, high = map(float, re.findall(r"[+-]\d\.\d{3}", versus))
    assert difference == pytest.approx(f1[1] - f1[0], abs=6e-4) and low <= difference <= high


def test_a_front_end_without_scores_has_no_best_threshold(synth_dataset, tmp_path, capsys):
    """Every colour-filter detection has confidence 1, so every threshold counts the same: none is "best", and
    the counts' threshold reads "any" rather than a fallback 0.50 the colour filter never uses."""
    assert main(["evaluate", str(synth_dataset), "--model", "colour-filter", "--out", str(tmp_path / "eval")]) == 0
    printed = capsys.readouterr().out.splitlines()
    assert re.search(r"any \(\d\.\d{3}\)", next(line for line in printed if "best-F1 threshold" in line))
    assert re.search(r"│\s+any\s+│", next(line for line in printed if "threshold (the counts')" in line))


def test_the_fit_plot_labels_its_log_axes_in_plain_numbers_at_1_2_and_5():
    """matplotlib's own labels for a decade-wide log axis ran into each other (2x10^1 3x10^1 4x10^1 ...)."""
    from detector.figures import log_log, plt

    fig, ax = plt.subplots()
    ax.plot([4, 120], [0.4, 12])
    log_log(ax)
    fig.canvas.draw()
    x_labels = {t.get_text() for t in ax.get_xticklabels()} - {""}
    y_labels = {t.get_text() for t in ax.get_yticklabels()} - {""}
    plt.close(fig)
    assert {"5", "10", "20", "50", "100"} <= x_labels and {"0.5", "1", "2", "5", "10"} <= y_labels
    assert not any("$" in label for label in x_labels | y_labels)


def test_the_best_threshold_is_the_best_f1s_and_none_when_every_threshold_counts_the_same():
    rows = [SweepPoint(c, 0.9, 0.9, f1) for c, f1 in ((0.25, 0.80), (0.5, 0.91), (0.75, 0.88))]
    assert best_threshold(rows) == 0.5
    assert best_threshold([replace(row, f1=0.59) for row in rows]) is None


@pytest.mark.parametrize("frames", [2, 7])
def test_the_per_image_chart_of_a_few_long_named_frames_fits_without_a_warning(frames, tmp_path):
    """Roboflow's file names run past 60 characters: written under a bar, they once outgrew the figure."""
    import warnings

    from detector.evaluation.plots import plot_per_image
    from detector.evaluation.results import FrameCounts

    rows = tuple(FrameCounts(f"IMG_20240612_15300{i}_jpg.rf.6c0f3a9b2e4d1f8a7c5b3e2d1a0f9e8d.jpg", Counts(1, 0, 1, 0))
                 for i in range(frames))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        png = plot_per_image(rows, tmp_path / "per_image.png", "shipped on frames with long names")
    assert cv2.imread(str(png)).shape[0] > 100
