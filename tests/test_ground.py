"""The camera's pose in the front end: foot-row range, the ground-plane gate, the crop to the band below the horizon,
and their use in measurements."""
from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from detector.synth.objects import WHITE, Cylinder, pole
from detector.synth.render import render_scene
from detector.synth.scene import Scene, _lighting, _room
from detector.synth.walk import render_walk, walk_camera_poses
from naoslam.camera import CameraPose, PinholeCamera
from naoslam.perception.detections import Detection, mask_centre_column, rotated_box_of_mask
from naoslam.perception.yolo import LandmarkDetector
from naoslam.ground import GroundView
from naoslam.landmarks import PoleGeometry
from naoslam.measurement import MeasurementModel, PowerLaw, RangeCalibration
from naoslam.sim import SimConfig, simulate

CAMERA = PinholeCamera()
POSE = CameraPose(z=0.5, pitch=math.radians(20), roll=math.radians(3))


def _rendered(cylinders: list[Cylinder], pose: CameraPose = POSE):
    rng = np.random.default_rng(0)
    scene = Scene(CAMERA, pose, _lighting(rng), _room(rng), cylinders=cylinders)
    return render_scene(scene)


def _ring(ranges, angle_deg: float = 8.0) -> list[Cylinder]:
    """Landmarks at the given ranges along alternating bearings, none hiding another."""
    out = []
    for i, r in enumerate(ranges):
        a = math.radians(angle_deg if i % 2 else -angle_deg) * (1 + i / len(ranges))
        out.append(pole("bp", r * math.cos(a), r * math.sin(a), PoleGeometry()))
    return out


def test_horizon_of_a_level_camera_is_the_principal_row():
    view = GroundView(CAMERA, CameraPose(z=0.5))
    assert view.horizon_row(100.0) == pytest.approx(CAMERA.cy, abs=1e-6)
    assert view.ground_point(320.0, 100.0) is None  # above the horizon: the ray never meets the floor


def test_foot_row_range_matches_the_renderer_within_2_percent_from_1_to_6_m():
    frame = _rendered(_ring([1.0, 1.5, 2.0, 3.0, 4.0, 5.0, 6.0]))
    view = GroundView(CAMERA, POSE)
    assert len(frame.poles) == 7
    for truth in frame.poles:
        assert not truth.partial
        foot = view.foot(truth.mask)
        assert foot.range_m == pytest.approx(truth.range_m, rel=0.02)
        assert foot.bearing_rad == pytest.approx(truth.bearing_rad, abs=math.radians(1.0))


def test_the_gate_keeps_real_poles_and_rejects_a_pole_on_a_wall_and_a_too_tall_tube():
    geometry = PoleGeometry()
    on_wall = pole("py", 3.0, 0.6, geometry)
    on_wall.base = on_wall.base + [0.0, 0.0, 0.45]  # a poster-like pole hanging half a metre up
    tall = Cylinder(np.array([2.5, -0.7, 0.0]), np.eye(3), 0.045, 1.2, ((0.0, 1.2, WHITE),))
    frame = _rendered(_ring([1.2, 2.0, 3.5, 5.0]) + [on_wall, tall])
    view = GroundView(CAMERA, POSE)
    real = [p for p in frame.poles if p.position_m[0] != 3.0]
    assert [view.check(p.mask) for p in real] == [None] * 4
    wall_mask = next(p for p in frame.poles if p.position_m[0] == 3.0).mask
    assert view.check(wall_mask) is not None
    # A distractor carries no mask of its own: render the tube alone, labelled, for its silhouette.
    tall.label = "tube"
    tube_mask = _rendered([tall]).poles[0].mask
    assert tube_mask.any() and view.check(tube_mask) == "reaches above the horizon: taller than the camera is high"


def _detection(mask: np.ndarray) -> Detection:
    rows, columns = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    return Detection(0, "bp", 0.99, (columns[0], rows[0], columns[-1] + 1, rows[-1] + 1), mask, (0, 0),
                     rotated_box_of_mask(mask), mask_centre_column(mask))


def test_measurements_use_the_foot_row_and_distrust_a_hidden_foot():
    calibration = RangeCalibration(PowerLaw(60.0, -1.0, 0.15), PowerLaw(200.0, -1.0, 0.15))
    model = MeasurementModel(calibration, min_confidence=0.5)
    truth = _rendered(_ring([3.0])).poles[0]
    with_pose = model.measure([_detection(truth.mask)], CAMERA.width, POSE, CAMERA.height)[0]
    without = model.measure([_detection(truth.mask)], CAMERA.width)[0]
    assert with_pose.source.endswith("+foot") and not without.source.endswith("+foot")
    assert abs(with_pose.range_m - truth.range_m) < abs(without.range_m - truth.range_m)
    assert with_pose.range_std < without.range_std
    hidden = truth.mask.copy()
    rows = np.flatnonzero(hidden.any(axis=1))
    hidden[rows[0] + (rows[-1] - rows[0]) // 3:] = False  # a robot in front hides the lower two thirds
    measured = model.measure([_detection(hidden)], CAMERA.width, POSE, CAMERA.height)[0]
    assert not measured.source.endswith("+foot")
    with pytest.raises(ValueError, match="image height"):
        model.measure([_detection(truth.mask)], CAMERA.width, POSE)


@pytest.mark.parametrize("width, height", [(0, None), (-1, None), (math.nan, None), (640, 0), (None, None)])
def test_a_frame_size_that_is_not_one_is_refused_not_turned_into_a_range(width, height):
    """A width of -1 measured every pole at 41.9 m and 90 degrees to the left; 0 ended in a ZeroDivisionError."""
    model = MeasurementModel(RangeCalibration(PowerLaw(60.0, -1.0, 0.15), PowerLaw(200.0, -1.0, 0.15)), 0.5)
    detection = _detection(_rendered(_ring([3.0])).poles[0].mask)
    pose = None if height is None else POSE
    with pytest.raises(ValueError, match="give the frame's size in pixels"):
        model.measure([detection], width, pose, height)


def test_a_pitched_cameras_pole_sizes_are_taken_to_what_a_level_camera_sees():
    """The range laws are fitted on a (nearly) level camera's sizes. Pitched 20 deg and rolled 3 deg, the camera
    sees the ring's poles up to 11 % taller than a level one (a pole 1.5 m away shorter); level_size gives the level
    camera's height to 2 %, and a measurement with the pose gets the range a level camera's frame would give."""
    ranges = [1.5, 2.5, 4.0, 6.0]
    level, pitched = _rendered(_ring(ranges), CameraPose(z=0.5)), _rendered(_ring(ranges))
    view = GroundView(CAMERA, POSE)
    stretch = []
    for flat, seen in zip(level.poles, pitched.poles):
        want, got = rotated_box_of_mask(flat.mask), rotated_box_of_mask(seen.mask)
        _, height = view.level_size(got.width, got.height, seen.range_m, seen.bearing_rad)
        assert height == pytest.approx(want.height, rel=0.02)
        stretch.append(abs(got.height / want.height - 1))
    assert max(stretch) > 0.08  # so a level_size that changed nothing would fail above
    assert GroundView(CAMERA, CameraPose(z=0.5)).level_size(9.0, 43.0, 6.0, 0.2) == pytest.approx((9.0, 43.0))

    calibration = RangeCalibration(PowerLaw(60.0, -1.0, 0.5), PowerLaw(250.0, -1.0, 0.02))  # height decides
    model = MeasurementModel(calibration, min_confidence=0.5, pitch_std_rad=math.radians(60))  # foot: no weight
    far_level, far_pitched = level.poles[-1], pitched.poles[-1]
    as_level = model.measure([_detection(far_level.mask)], CAMERA.width)[0].range_m
    with_pose = model.measure([_detection(far_pitched.mask)], CAMERA.width, POSE, CAMERA.height)[0].range_m
    without_pose = model.measure([_detection(far_pitched.mask)], CAMERA.width)[0].range_m
    assert with_pose == pytest.approx(as_level, rel=0.025)
    assert without_pose < 0.92 * as_level


def _bgr(frame) -> np.ndarray:
    return cv2.cvtColor((frame.image * 255 + 0.5).astype(np.uint8), cv2.COLOR_RGB2BGR)


def test_the_front_end_gates_a_pole_hanging_on_the_wall_and_its_crop_never_sees_it():
    pose = CameraPose(z=0.5, pitch=math.radians(12))
    hanging = pole("py", 2.5, 0.5, PoleGeometry())
    hanging.base = hanging.base + [0.0, 0.0, 0.3]
    image = _bgr(_rendered([pole("bp", 2.0, -0.4, PoleGeometry()), hanging], pose))
    detector = LandmarkDetector()
    assert sorted(d.name for d in detector(image)) == ["bp", "py"]
    assert [d.name for d in detector(image, pose, crop=False)] == ["bp"]
    assert [d.name for d, _ in detector.gate_rejections] == ["py"] and detector.gate_rejected == 1
    assert [d.name for d in detector(image, pose)] == ["bp"]


def test_the_band_below_the_horizon_gives_the_whole_frames_detections():
    walk = simulate(SimConfig(seed=0, duration_s=6))
    frames, poses = render_walk(walk, progress=False, workers=1), walk_camera_poses(walk)
    detector = LandmarkDetector()
    assert detector.any_input_size
    compared = 0
    for frame, pose in zip(frames, poses):
        assert GroundView(CAMERA, pose).band_top() > 100  # the walk's head pitch: a third of the frame is skipped
        band, whole = detector(frame, pose), detector(frame, pose, crop=False)
        assert [d.name for d in band] == [d.name for d in whole]
        for a, b in zip(band, whole):
            assert np.abs(np.subtract(a.box, b.box)).max() < 5.0
            compared += 1
    assert compared >= 10


@pytest.mark.parametrize("field", ["z", "pitch", "roll", "yaw"])
def test_a_camera_pose_that_is_not_finite_is_refused_by_name(field):
    """A failed joint reading used to end deep in the gate as "cannot convert float NaN to integer"."""
    with pytest.raises(ValueError, match=f"'{field}': nan"):
        CameraPose(**{field: math.nan})


@pytest.mark.parametrize("pose", [CameraPose(z=0.0), CameraPose(z=-0.5), CameraPose(z=0.5, pitch=3.0),
                                  CameraPose(z=0.5, roll=-1.6)])
def test_a_pose_with_no_ground_plane_is_refused_in_words(pose):
    """Before: ZeroDivisionError at height 0, OverflowError when upside down, silent nonsense below the floor."""
    with pytest.raises(ValueError, match="leave the pose out for this frame"):
        GroundView(CAMERA, pose)


def test_a_maybe_threshold_measures_the_detections_below_the_threshold_as_tentative():
    from naoslam.perception.detections import Detection

    calibration = RangeCalibration(PowerLaw(60.0, -1.0, 0.15), PowerLaw(200.0, -1.0, 0.15))
    found = [Detection.from_box("bp", confidence, (300, 200, 320, 280)) for confidence in (0.9, 0.5, 0.2)]
    sure = MeasurementModel(calibration, 0.85).measure(found, 640)
    assert [(m.confidence, m.tentative) for m in sure] == [(0.9, False)]
    maybe = MeasurementModel(calibration, 0.85, maybe_confidence=0.4).measure(found, 640)
    assert [(m.confidence, m.tentative) for m in maybe] == [(0.9, False), (0.5, True)]
    with pytest.raises(ValueError, match="at most the operating threshold"):
        MeasurementModel(calibration, 0.85, maybe_confidence=0.9)
