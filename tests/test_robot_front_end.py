"""The robot's two-stage front end: candidates at full resolution, the crop network, box-only detections measured,
gated and scored like masks."""
from __future__ import annotations

import json
import math
import subprocess
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from detector.formats import read_record
from detector.crops.network import CropArchitecture
from detector.crops.samples import NO_POLE, coverage, crops_of_dataset, ground_view, label_boxes, pole_for
from detector.crops.second_look import second_look_crops
from detector.datasets.io import load_dataset
from detector.datasets.truth import load_camera_poses
from detector.evaluation.counting import evaluate_image
from detector.evaluation.results import Counts
from detector.synth.backdrops import scan_backdrops
from detector.synth.generate import SynthJob, generate_dataset
from detector.synth.render import render_scene
from detector.synth.scene import SceneConfig, calibration_scene
from naoslam.camera import PinholeCamera
from naoslam.perception.candidates import (BAND_PER_WIDTH, MAX_CANDIDATES, MAX_CANDIDATES_WITHOUT_POSE,
                                           CandidateFinder, window_around_box)
from naoslam.perception.preclassifier import preclassifier_entry
from naoslam.perception.two_stage import REFINE_CONF, CropDetector
from naoslam.perception.crops import crop_window, to_crop, to_frame
from naoslam.perception.detections import Detection
from naoslam.perception.yolo import LandmarkDetector
from naoslam.perception.loading import load_detector
from naoslam.ground import GroundView, PoleExtent
from naoslam.landmarks import CLASSES, PoleGeometry
from detector.model_files import ROBOT_WEIGHTS
from tests.conftest import REPOSITORY, assert_runs_without_training_side

CROP_WH = (24, 72)
#: A small crop network of every kind of layer the shipped one may have: a full-resolution convolution, strided ones,
#: the crop's normalising.
TINY = CropArchitecture(CROP_WH, (8, 8, 16), (1, 2, 2), 16, normalise=True)


def _rendered(code: str, range_m: float, angle_deg: float, seed: int):
    """A 640x480 frame of one pole, its box and the camera's ground view."""
    camera = PinholeCamera(640, 480)
    scene = calibration_scene(np.random.default_rng(seed), camera, code, range_m, angle_deg)
    frame = render_scene(scene)
    rows, columns = np.nonzero(frame.poles[0].mask)
    box = (float(columns.min()), float(rows.min()), float(columns.max() + 1), float(rows.max() + 1))
    image = cv2.cvtColor((frame.image * 255 + 0.5).astype(np.uint8), cv2.COLOR_RGB2BGR)
    return image, box, GroundView(camera, scene.pose)


def _yuyv(bgr: np.ndarray) -> np.ndarray:
    """The camera's full-range YUYV buffer of a BGR frame (each pixel pair's chroma averaged)."""
    ycrcb = cv2.cvtColor(bgr, cv2.COLOR_BGR2YCrCb).astype(np.float32)
    pairs = (ycrcb[:, 0::2] + ycrcb[:, 1::2]) / 2
    out = np.empty(bgr.shape[:2] + (2,), np.uint8)
    out[..., 0] = ycrcb[..., 0]
    out[:, 0::2, 1] = np.round(pairs[..., 2])  # U (Cb)
    out[:, 1::2, 1] = np.round(pairs[..., 1])  # V (Cr)
    return out


@pytest.mark.parametrize("code, range_m, angle", [("pb", 0.75, 0.0), ("gp", 2.0, 10.0), ("py", 4.0, -20.0),
                                                  ("bp", 6.0, 0.0), ("yp", 8.0, 10.0), ("pg", 9.0, -10.0)])
def test_a_candidate_frames_each_rendered_pole_near_and_far(code, range_m, angle):
    image, box, view = _rendered(code, range_m, angle, seed=3)
    for found in (CandidateFinder()(image, view), CandidateFinder()(image)):
        assert any(pole_for(c.window, [box], image.shape[:2]) == 0 for c in found), (code, range_m, found)


def test_with_the_pose_only_the_band_below_the_horizon_is_searched():
    image, box, view = _rendered("pb", 3.0, 0.0, seed=4)
    above = image.copy()
    top = view.band_top()
    above[:top] = (180, 60, 230)  # pink sky: no pole can stand there
    assert all(c.anchor[1] >= top for c in CandidateFinder()(above, view))
    assert any(c.anchor[1] < top for c in CandidateFinder()(above))


def test_without_the_pose_a_pole_read_by_its_pink_band_alone_is_not_crowded_out_by_junctions_of_clutter():
    image, box, _ = _rendered("pb", 3.0, 0.0, seed=3)
    x0, y0, x1, y1 = (int(v) for v in box)
    band = (y1 - y0) // 4
    image[y0 + band:y0 + 2 * band + 2, x0:x1] = 50  # the blue band too dark to read: no junction, a pink blob
    for column in range(8):
        for row in range(2):
            x, y = 20 + column * 78, 20 + row * 80
            image[y:y + 12, x:x + 6] = (180, 60, 230)  # a thin pink mark on a wide blue one: a junction each
            image[y + 12:y + 24, x - 20:x + 26] = (230, 160, 60)
    found = CandidateFinder(max_candidates=8)(image)
    assert sum(c.kind == "junction" for c in found) > 4
    assert any(pole_for(c.window, [box], image.shape[:2]) == 0 for c in found)


def _pole_width_at(view: GroundView, u: float, v: float) -> float:
    """The width in pixels of a pole whose line between the bands shows at (u, v)."""
    pole = PoleGeometry()
    return pole.diameter * float(view.pixels_per_metre(np.array([u]), np.array([v]), pole.divide_height)[0])


def test_with_the_pose_a_piece_of_a_near_pole_s_junction_outranks_clutter_too_wide_for_its_place():
    _, _, view = _rendered("pb", 3.0, 0.0, seed=3)
    image = np.full((480, 640, 3), 128, np.uint8)
    u, v = 420, 400  # a near pole's line between its bands
    width = _pole_width_at(view, u, v)
    band = int(BAND_PER_WIDTH * width)
    x0, x1 = int(u - width / 2), int(u + width / 2)
    image[v - band:v, x0:x1] = (180, 60, 230)  # its pink band whole
    image[v:v + 6, u - 3:u + 3] = (230, 160, 60)  # its blue band reads in one narrow piece under it
    box = (float(x0), float(v - band), float(x1), float(v + 2 * band))
    clutter_u, clutter_v = 100, 300  # a pink over blue edge 2.5 times as wide as a pole there
    wide = int(2.5 * _pole_width_at(view, clutter_u, clutter_v))
    image[clutter_v - 8:clutter_v, clutter_u:clutter_u + wide] = (180, 60, 230)
    image[clutter_v:clutter_v + 8, clutter_u:clutter_u + wide] = (230, 160, 60)
    first = CandidateFinder(max_candidates=1)(image, view)
    assert pole_for(first[0].window, [box], image.shape[:2]) == 0, first


def test_a_busy_frame_keeps_more_windows_with_the_pose_than_without_and_a_cap_asked_for_holds_both():
    _, _, view = _rendered("pb", 3.0, 0.0, seed=3)
    image = np.full((480, 640, 3), 128, np.uint8)
    for row in range(4):
        for column in range(16):  # 64 small pink over blue marks just below the horizon
            x, y = 8 + column * 40, view.band_top() + 12 + row * 24
            image[y - 6:y, x:x + 8] = (180, 60, 230)
            image[y:y + 6, x:x + 8] = (230, 160, 60)
    assert (len(CandidateFinder()(image, view)), len(CandidateFinder()(image))) == \
        (MAX_CANDIDATES, MAX_CANDIDATES_WITHOUT_POSE)
    assert (len(CandidateFinder(10)(image, view)), len(CandidateFinder(10)(image))) == (10, 10)


def test_with_the_pose_the_candidates_cover_back_lit_poles(tmp_path):
    rng = np.random.default_rng(1)
    (tmp_path / "backgrounds").mkdir()
    ramp = np.linspace(0, 1, 640)[None, :, None] * rng.uniform(40, 120, 3) + rng.uniform(40, 120, 3)
    room = np.clip(ramp + rng.normal(0, 12, (480, 640, 3)), 0, 255).astype(np.uint8)
    cv2.imwrite(str(tmp_path / "backgrounds" / "room.jpg"), room)
    job = SynthJob(24, seed=7, backgrounds=scan_backdrops(tmp_path / "backgrounds"), backdrop_share=1.0,
                   config=SceneConfig(backlight_share=1.0))
    dataset = load_dataset(generate_dataset(tmp_path / "backlit", job, workers=1, progress=False))
    poses = load_camera_poses(dataset)
    covered = []
    for sample in dataset.samples:
        image = cv2.imread(str(sample.image))
        found = CandidateFinder()(image, ground_view(poses[sample.image.name], image.shape[:2]))
        covered += [any(coverage(c.window, box) >= 0.7 for c in found)
                    for box in label_boxes(sample, image.shape[1], image.shape[0])]
    assert len(covered) >= 20 and np.mean(covered) >= 0.75, covered


def test_the_camera_s_yuyv_buffer_gives_the_candidates_of_its_bgr_frame():
    image, box, view = _rendered("gp", 3.0, 0.0, seed=6)
    from_yuyv = CandidateFinder()(_yuyv(image), view)
    assert any(pole_for(c.window, [box], image.shape[:2]) == 0 for c in from_yuyv)
    crop = crop_window(_yuyv(image), from_yuyv[0].window, CROP_WH)
    assert np.abs(crop.astype(int) - crop_window(image, from_yuyv[0].window, CROP_WH)).mean() < 6


@settings(max_examples=60, deadline=None)
@given(st.floats(-50, 600), st.floats(-50, 400), st.floats(4, 200), st.floats(0.05, 0.95), st.floats(0.05, 0.95))
def test_boxes_go_to_the_crop_and_back_unchanged(x0, y0, size, left, top):
    window = (x0, y0, x0 + size, y0 + 3 * size)
    box = (x0 + left * size * 0.5, y0 + top * size, x0 + size * 0.9, y0 + 2.5 * size)
    back = to_frame(to_crop(box, window)[None], np.array([window]))[0]
    assert np.allclose(back, box, atol=1e-6)


def test_a_window_reaching_outside_the_frame_is_black_there():
    frame = np.full((100, 100, 3), 200, np.uint8)
    crop = crop_window(frame, (-50.0, 0.0, 50.0, 300.0), (24, 72))
    assert crop[:, :10].max() == 0 and crop[:20, 14:].min() == 200 and crop[-20:].max() == 0


@pytest.fixture(scope="module")
def tiny_crop_model(synth_dataset, tmp_path_factory):
    """The crop network trained for two epochs on the session's rendered frames, exported to ONNX: its path, its
    crops, its epochs and the network."""
    from detector.crops.export import export_crop_network
    from detector.crops.network import PoleCropNet
    from detector.crops.settings import CropTrainSettings
    from detector.crops.train import train_crop_network

    crops = crops_of_dataset(load_dataset(synth_dataset), ("train", "valid", "test"), CROP_WH, progress=False)
    network, history = train_crop_network(crops, crops, CropTrainSettings(epochs=2, batch=64, threads=1),
                                          PoleCropNet(TINY), log=lambda line: None)
    path = tmp_path_factory.mktemp("crops") / "crops.onnx"
    export_crop_network(network, path, crops.crops[:32], conf=0.3)
    return path, crops, history, network


def test_the_crop_set_names_poles_and_backgrounds_with_boxes_for_poles(tiny_crop_model):
    _, crops, _, _ = tiny_crop_model
    poles = crops.classes != NO_POLE
    assert poles.any() and (~poles).any()
    assert np.isfinite(crops.boxes[poles]).all() and np.isnan(crops.boxes[~poles]).all()
    assert (crops.boxes[poles, 2] > crops.boxes[poles, 0]).all() and (crops.boxes[poles, 3] > crops.boxes[poles, 1]).all()


def test_the_crop_network_trains_and_its_export_loads_as_the_two_stage_front_end(tiny_crop_model, synth_dataset):
    path, _, history, _ = tiny_crop_model
    assert len(history) == 2 and history[-1].loss < history[0].loss
    detector = load_detector(path, conf=0.01)
    assert isinstance(detector, CropDetector) and detector.size_wh == CROP_WH
    frame = cv2.imread(str(sorted((synth_dataset / "train" / "images").glob("*.jpg"))[0]))
    found = detector(frame)
    assert all(d.box_only and d.name in CLASSES and 0 < d.confidence <= 1 for d in found)
    with pytest.raises(ValueError, match="two-stage robot model"):
        LandmarkDetector(path)


def test_the_crop_network_runs_in_openvino_at_the_atoms_instruction_set_as_in_pytorch(tiny_crop_model):
    """The crop's normalising once compiled into an OpenVINO MVN node that fails under the SSE4.1 cap (or answered
    with no rows): the exported network, normalising and a full-resolution convolution included, gives PyTorch's
    answers there."""
    pytest.importorskip("openvino")
    from detector.speed import worker_environment

    path, crops, _, _ = tiny_crop_model
    blob = np.ascontiguousarray(crops.crops[:8].transpose(0, 3, 1, 2), np.float32) / 255.0
    expected = ort_output(path, blob)
    code = ("import sys, numpy as np; from naoslam.perception.engines import OpenVinoForward; "
            "blob = np.load(sys.argv[1]); np.save(sys.argv[1], OpenVinoForward(sys.argv[2], 1)(blob)[0])")
    with tempfile.TemporaryDirectory() as folder:
        saved = str(Path(folder) / "blob.npy")
        np.save(saved, blob)
        subprocess.run([sys.executable, "-c", code, saved, str(path)], env=worker_environment(capped=True),
                       check=True, capture_output=True)
        answered = np.load(saved)
    assert answered.shape == expected.shape and np.abs(answered - expected).max() < 1e-4


def ort_output(path, blob: np.ndarray) -> np.ndarray:
    """The exported crop network's answers through onnxruntime (which the export checked against PyTorch)."""
    import onnxruntime as ort

    session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    return session.run(None, {session.get_inputs()[0].name: blob})[0]


@pytest.mark.parametrize("keep", ["best", "last"])
def test_the_crop_network_keeps_the_best_epoch_or_the_last_as_asked(tiny_crop_model, keep):
    """A fine-tune's valid split of a frame or two scores every epoch alike: ``best`` would keep the first."""
    from detector.crops.network import PoleCropNet
    from detector.crops.settings import CropTrainSettings
    from detector.crops.train import train_crop_network, validate

    _, crops, _, _ = tiny_crop_model
    network, history = train_crop_network(crops, crops, CropTrainSettings(epochs=3, batch=64, threads=1, keep=keep),
                                          PoleCropNet(TINY), log=lambda line: None)
    kept = history[-1] if keep == "last" else max(history, key=lambda epoch: epoch.score)
    assert validate(network, crops) == pytest.approx((kept.pole_recall, kept.false_pole_rate, kept.box_iou))
    with pytest.raises(ValueError, match="give best or last"):
        CropTrainSettings(keep="first")
    with pytest.raises(ValueError, match="second-look epochs -1: give 0"):
        CropTrainSettings(second_look_epochs=-1)


def test_the_distillation_targets_are_the_teacher_s_scores_not_the_labels(tiny_crop_model):
    """What the student learns beside the labels is the teacher's class scores on each crop: they rank the classes as
    the teacher does, and they are soft where a label is one-hot."""
    import torch

    from detector.crops.train import teacher_logits, tensors

    _, crops, _, teacher = tiny_crop_model
    images, classes, _ = tensors(crops)
    targets = teacher_logits(teacher, images)
    with torch.no_grad():
        expected = teacher.eval()(images)[:, :NO_POLE + 1]
    assert torch.allclose(targets, expected, atol=1e-5)
    probabilities = torch.softmax(targets, dim=1)
    one_hot = torch.nn.functional.one_hot(classes, NO_POLE + 1).float()
    assert (probabilities - one_hot).abs().sum(dim=1).mean() > 0.1


def test_a_student_learns_what_its_teacher_says_where_the_labels_say_otherwise(tiny_crop_model):
    """A teacher sure that no crop holds a pole pulls a student trained on the same labelled crops away from poles:
    the distillation loss reaches the training."""
    import torch

    from detector.crops.network import PoleCropNet
    from detector.crops.settings import CropTrainSettings
    from detector.crops.train import tensors, train_crop_network

    _, crops, _, _ = tiny_crop_model
    doubter = PoleCropNet(TINY)
    with torch.no_grad():
        final = doubter.head[-1]
        final.weight[:NO_POLE + 1] = 0
        final.bias[:NO_POLE + 1] = -8.0
        final.bias[NO_POLE] = 8.0
    settings = CropTrainSettings(epochs=2, batch=64, threads=1, keep="last")
    images, classes, _ = tensors(crops)
    poles = classes != NO_POLE

    def pole_probability(teacher) -> float:
        student, _ = train_crop_network(crops, crops, settings, PoleCropNet(TINY), log=lambda line: None,
                                        teacher=teacher)
        with torch.no_grad():
            return float(torch.softmax(student(images[poles])[:, :NO_POLE + 1], dim=1)[:, :NO_POLE].sum(1).mean())

    assert pole_probability(doubter) < pole_probability(None) - 0.05


def test_train_robot_prints_and_keeps_what_it_made(synth_dataset, tmp_path, capsys):
    """`poles train-robot`'s summary is printed and kept in history.json, both reading back as one typed result."""
    from detector.cli import main
    from detector.robot_training import RobotTraining

    out = tmp_path / "robot"
    assert main(["train-robot", str(synth_dataset), "--out", str(out), "--epochs", "1", "--threads", "1",
                 "--weights", str(ROBOT_WEIGHTS), "--second-look-epochs", "1", "--teacher", str(ROBOT_WEIGHTS)]) == 0
    lines = capsys.readouterr().out.splitlines()
    printed = RobotTraining.from_json(json.loads("\n".join(lines[lines.index("{"):])))
    kept = read_record(out / "history.json", "robot training")
    assert RobotTraining.from_json({k: v for k, v in kept.items() if k != "history"}) == printed
    assert printed.epochs == len(kept["history"]) == 2 and printed.model == out / "poles-robot.onnx"
    assert [row["epoch"] for row in kept["history"]] == [1, 2] and printed.best_epoch.epoch == 2
    assert printed.second_look_crops > 0 and any(line.startswith("second looks: ") for line in lines)
    assert printed.teacher == ROBOT_WEIGHTS and kept["teacher"] == str(ROBOT_WEIGHTS)
    assert isinstance(load_detector(printed.model), CropDetector) and 0 < printed.operating_conf < 1
    assert printed.preclassifier is not None and printed.preclassifier.kept_poles >= 0.99
    assert load_detector(printed.model).preclassifier.threshold == pytest.approx(printed.preclassifier.threshold)


def test_train_robot_adds_a_preclassifier_to_a_trained_network_and_leaves_the_network_as_it_was(synth_dataset,
                                                                                                tmp_path):
    from detector.cli import main

    out = tmp_path / "robot"
    assert main(["train-robot", str(synth_dataset), "--out", str(out), "--epochs", "0", "--threads", "1",
                 "--weights", str(ROBOT_WEIGHTS), "--preclassifier-epochs", "1"]) == 0
    trained, shipped = CropDetector(out / "poles-robot.onnx"), CropDetector("shipped-robot", preclassify=False)
    assert trained.preclassifier is not None
    crops = np.random.default_rng(0).random((4, 3, 48, 24), dtype=np.float32)
    assert np.abs(trained.forward(crops) - shipped.forward(crops)).max() < 1e-4
    history = read_record(out / "history.json", "robot training")
    assert history["epochs"] == 0 and history["best_epoch"] is None and history["preclassifier"]["parameters"] > 0


def test_a_second_look_goes_to_each_likely_pole_s_box_at_its_own_scale():
    detector = CropDetector("shipped-robot")
    out = np.zeros((6, len(CLASSES) + 1 + 4), np.float32)
    out[0, 2], out[1, 0], out[2, 4], out[3, 1], out[4, 3], out[5, 5] = 0.5, REFINE_CONF / 2, 0.9, 0.4, 0.7, 0.8
    boxes = np.array([[100, 50, 120, 130], [200, 60, 220, 140], [300, 70, 300, 150],  # the third no wider than 0
                      [101, 52, 121, 131],  # the first pole again, less sure: one second look per pole
                      [10, 20, 30, 100], [250, 10, 262, 58]], float)
    first = np.array([[80, 10, 140, 190], [190, 40, 230, 160], [290, 50, 310, 170], [80, 10, 140, 190],
                      window_around_box(tuple(boxes[4]), (240, 320)),  # already framed at its own scale
                      [200, 0, 300, 200]], float)
    again, windows = detector.second_look_windows(out, boxes, first, (240, 320))
    assert sorted(again.tolist()) == [0, 5]
    assert windows[again.tolist().index(0)].tolist() == list(window_around_box(tuple(boxes[0]), (240, 320)))


def test_second_look_crops_hold_the_poles_the_first_look_finds_centred(synth_dataset):
    """Each second look the shipped network takes at a rendered pole becomes a crop of that pole, the pole standing
    in the middle of it at its own scale, as the robot sees it the second time; some look at clutter."""
    crops = second_look_crops(CropDetector("shipped-robot", threads=1), [load_dataset(synth_dataset)], "train",
                              progress=False)
    poles = crops.classes != NO_POLE
    assert poles.sum() >= 10 and len(crops.crops) == len(crops.classes) == len(crops.boxes)
    centres, heights = (crops.boxes[poles, 0] + crops.boxes[poles, 2]) / 2, crops.boxes[poles, 3] - crops.boxes[poles, 1]
    assert np.median(np.abs(centres - 0.5)) < 0.03 and 0.58 < np.median(heights) < 0.72  # 4 bands of 6
    assert np.isnan(crops.boxes[~poles]).all()


@pytest.fixture(scope="module")
def tiny_cascade(tiny_crop_model, synth_dataset, tmp_path_factory):
    """The tiny crop network with a preclassifier trained for two epochs on the same windows, stored in its file."""
    import torch

    from detector.crops.preclassifier import PRECLASSIFIER_SIZE_WH, preclassifier_onnx, train_preclassifier
    from detector.crops.settings import CropTrainSettings
    from detector.model_files import add_metadata

    path, crops, _, network = tiny_crop_model
    small = crops_of_dataset(load_dataset(synth_dataset), ("train", "valid", "test"), PRECLASSIFIER_SIZE_WH,
                             progress=False)
    preclassifier, result = train_preclassifier(small, small, crops, network,
                                                CropTrainSettings(epochs=2, batch=64, threads=1),
                                                log=lambda line: None)
    graph = preclassifier_onnx(preclassifier, small.crops[:16])
    model = tmp_path_factory.mktemp("cascade") / "cascade.onnx"
    model.write_bytes(path.read_bytes())
    add_metadata(model, preclassifier=preclassifier_entry(graph, result.threshold, result.kept_poles,
                                                          result.rejected_clutter))
    with torch.no_grad():
        expected = torch.sigmoid(preclassifier(torch.from_numpy(
            small.crops[:8].transpose(0, 3, 1, 2).astype(np.float32) / 255.0)))[:, 0].numpy()
    return model, small, result, expected


def test_the_preclassifier_keeps_the_poles_the_crop_network_names_and_rejects_clutter(tiny_cascade):
    _, small, result, _ = tiny_cascade
    assert small.crops.shape[1:3] == (24, 12)
    assert result.kept_poles >= 0.99 and 0 <= result.rejected_clutter <= 1 and result.parameters < 10_000


def test_the_preclassifier_in_the_model_file_runs_torch_free_at_the_atoms_instruction_set(tiny_cascade):
    """The graph stored in the crop network's metadata gives PyTorch's answers through onnxruntime, and through
    OpenVINO in a process capped at the Atom's instruction set; loading it imports nothing of the training side."""
    pytest.importorskip("openvino")
    from detector.speed import worker_environment

    model, small, _, expected = tiny_cascade
    blob = np.ascontiguousarray(small.crops[:8].transpose(0, 3, 1, 2), np.float32) / 255.0
    detector = CropDetector(model, threads=1)
    assert detector.preclassifier is not None and detector.preclassifier.size_wh == (12, 24)
    assert np.abs(detector.preclassifier.scores(blob) - expected).max() < 1e-4
    code = ("import sys, numpy as np; from naoslam.perception.two_stage import CropDetector; "
            "blob = np.load(sys.argv[1]); detector = CropDetector(sys.argv[2], threads=1, engine='openvino'); "
            "np.save(sys.argv[1], detector.preclassifier.scores(blob)); "
            "bad = [m for m in ('torch', 'ultralytics', 'detector') if m in sys.modules]; sys.exit(1 if bad else 0)")
    with tempfile.TemporaryDirectory() as folder:
        saved = str(Path(folder) / "blob.npy")
        np.save(saved, blob)
        result = subprocess.run([sys.executable, "-c", code, saved, str(model)], env=worker_environment(capped=True),
                                capture_output=True, text=True)
        assert result.returncode == 0, result.stderr[-2000:]
        assert np.abs(np.load(saved) - expected).max() < 1e-4


def test_the_window_budget_holds_on_a_frame_full_of_pink_clutter(tiny_cascade):
    """Pink over blue stripes everywhere: the finder fills its cap, and with a preclassifier that passes every window
    the crop network still looks at no more than the budget, and the front end says the frame hit it."""
    model, _, _, _ = tiny_cascade
    frame = np.zeros((480, 640, 3), np.uint8)
    for row in range(0, 480, 16):
        frame[row:row + 8] = (90, 40, 230) if (row // 16) % 2 else (200, 60, 30)  # pink, then blue (BGR)
    frame[:, ::40] = 255  # cut into columns, so there are many anchors
    detector = CropDetector(model, threads=1, conf=0.01, window_budget=3)
    detector.preclassifier.threshold = 0.0
    detector(frame)
    assert detector.cost.windows == MAX_CANDIDATES_WITHOUT_POSE
    assert detector.cost.looked_at == 3 and detector.cost.hit_budget and detector.cost.second_looks <= 3
    everything = CropDetector(model, threads=1, conf=0.01, preclassify=False)
    everything(frame)
    assert everything.cost.looked_at == MAX_CANDIDATES_WITHOUT_POSE and not everything.cost.hit_budget
    with pytest.raises(ValueError, match="window budget 0"):
        CropDetector(model, window_budget=0)


def test_the_shipped_robot_model_carries_a_preclassifier_that_rejects_most_windows_of_real_clutter():
    """Frames without poles (photographs a pole model never saw) fill the finder's windows; the shipped
    preclassifier lets at most the budget through to the crop network."""
    detector = CropDetector("shipped-robot", threads=1)
    assert detector.preclassifier is not None
    looked = []
    for name in ("astronaut", "coffee", "chelsea", "rocket"):
        from skimage import data as images

        frame = cv2.cvtColor(getattr(images, name)(), cv2.COLOR_RGB2BGR)
        detector(frame)
        looked.append((detector.cost.windows, detector.cost.looked_at))
    assert sum(w for w, _ in looked) > 20 and sum(k for _, k in looked) <= sum(w for w, _ in looked) / 2, looked


def test_the_two_stage_front_end_runs_without_the_training_side(tiny_crop_model):
    path, _, _, _ = tiny_crop_model
    assert_runs_without_training_side(
        f"import naoslam; naoslam.load_detector({str(path)!r}, conf=0.01)(np.zeros((240, 320, 3), np.uint8))")


def test_a_box_only_front_end_is_scored_by_box_iou():
    mask = np.zeros((100, 100), bool)
    mask[20:80, 40:52] = True
    mask[20:24, 40:44] = False  # a mask IoU below the box IoU
    hit = Detection.from_box("pb", 0.9, (40, 20, 52, 80))
    off = Detection.from_box("pb", 0.9, (46, 20, 58, 80))  # half a pole to the side
    by_box = evaluate_image("f", ["pb"], [mask], [None], [hit, off], mask.shape, "box")
    assert by_box.overlap[0, 0] == pytest.approx(1.0) and by_box.overlap[1, 0] == pytest.approx(6 / 18)
    assert by_box.counts(0.5) == Counts(tp=1, fp=1)
    by_mask = evaluate_image("f", ["pb"], [mask], [None], [hit], mask.shape, "mask")
    assert by_mask.overlap[0, 0] < 1.0


def test_a_box_gives_the_extent_of_the_mask_that_fills_it():
    mask = np.zeros((60, 40), bool)
    mask[10:50, 12:20] = True
    from_mask = Detection.from_mask("gp", 1.0, mask)
    from_box = Detection.from_box("gp", 1.0, from_mask.box)
    assert from_box.extent == from_mask.extent == PoleExtent((16.0, 10.0), (16.0, 50.0))
    assert (from_box.rotated_box.width, from_box.rotated_box.height) == (8.0, 40.0)
    assert from_box.centre_column == from_mask.centre_column and from_box.full_mask(mask.shape).sum() == mask.sum()


def test_the_ground_gate_judges_a_box_as_the_mask_it_bounds():
    image, box, view = _rendered("py", 3.0, 0.0, seed=9)
    assert view.check_extent(PoleExtent.of_box(box)) is None
    tall = (box[0], box[1] - 2 * (box[3] - box[1]), box[2], box[3])
    assert "px tall" in view.check_extent(PoleExtent.of_box(tall)) or "horizon" in view.check_extent(
        PoleExtent.of_box(tall))


def test_the_finder_s_window_around_a_box_holds_the_pole_at_its_scale():
    box = (300.0, 200.0, 312.0, 250.0)
    window = window_around_box(box, (480, 640))
    assert pole_for(window, [box], (480, 640)) == 0
    assert math.isclose((window[3] - window[1]) / (box[3] - box[1]), 1.5)


def _machine_has_avx2() -> bool:
    from numpy._core._multiarray_umath import __cpu_features__

    return bool(__cpu_features__.get("AVX2"))


@pytest.mark.skipif(not _machine_has_avx2(), reason="this CPU has no AVX2: an uncapped library looks capped here")
@pytest.mark.parametrize("dropped", [None, "ONEDNN_MAX_CPU_ISA", "NPY_DISABLE_CPU_FEATURES", "OPENCV_CPU_DISABLE"])
def test_the_robot_timing_refuses_to_time_when_a_cap_is_off(dropped):
    from detector.speed import worker_environment

    env = worker_environment(capped=True)
    env.pop(dropped, None)
    code = "import json; from detector.speed import caps_in_force; print(json.dumps(caps_in_force()))"
    result = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    problems = json.loads(result.stdout.strip().splitlines()[-1])
    assert (problems == []) == (dropped is None), problems
