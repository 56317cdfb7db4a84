"""`poles slam` end to end: outputs of a simulated walk, the comparison table, recorded frames, bad input."""
from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from detector.formats import read_record
from detector.cli import main
from detector.slam.comparison import BACKENDS, REFERENCE_ROW, BackendRow
from detector.slam.sequences import FrontEndSpec, recorded_sequence
from naoslam.landmarks import CLASSES
from naoslam.measurement import PowerLaw, RangeCalibration
from naoslam.runner import run_slam


#: The colour filter with a colour law of its own, as a recording's front end.
COLOUR_FILTER = FrontEndSpec("colour-filter", RangeCalibration(PowerLaw(50, -1), PowerLaw(220, -1),
                                                           colour_law=PowerLaw(6.2, -1.0, 0.03)))

def test_slam_command_writes_metrics_map_path_plots_and_comparison(tmp_path, capsys):
    out = tmp_path / "slam"
    assert main(["slam", "--sim", "square", "--duration", "30", "--backend", "fej", "--lookalikes", "1",
                 "--compare", "2", "--out", str(out)]) == 0
    metrics = read_record(out / "metrics.json", "slam")
    for key in ("robot_error", "landmark_error"):
        assert set(metrics[key]) >= {"mean", "std", "rmse"}
    assert metrics["label"] == "FEJ-EKF + odometry scales + NN association + separation 0.5 m + gate 9.21 + min view 3"
    assert {"nees", "nis", "counts", "time_per_step_us", "phantoms", "landmarks_missing"} <= set(metrics)
    rows = [BackendRow.from_json(row) for row in read_record(out / "comparison.json", "slam comparison")["rows"]]
    assert [row.backend for row in rows] == [*BACKENDS, REFERENCE_ROW] and all(row.seeds == 2 for row in rows)
    reference = rows[-1]
    assert reference.landmark_error < rows[0].landmark_error and reference.phantoms == 0
    by_name = {row.backend: row for row in rows}
    ekf, eif = by_name["EKF localisation, known map"], by_name["EIF localisation, known map"]
    pose_only = by_name["EKF localisation, known map, no odometry scales (thesis)"]
    assert ekf.landmark_error is None and ekf.robot_error == pytest.approx(eif.robot_error, abs=0.005)
    assert 3 * ekf.robot_error < pose_only.robot_error and ekf.nees < pose_only.nees / 10
    for name in ("map.png", "errors.png"):
        assert cv2.imread(str(out / name)) is not None
    assert len((out / "path.csv").read_text().splitlines()) == 301 + 1
    assert {name.split("#")[0] for name in read_record(out / "map.json", "slam map")["landmarks"]} <= set(CLASSES)
    assert "back ends on sim square" in capsys.readouterr().out


@pytest.mark.parametrize("argv, message", [(["--min-views", "0"], "at least 1"), (["--gate", "-1"], "positive"),
                                          (["--min-separation", "-0.1"], "0 or more"),
                                          (["--frames", "x"], "--frames needs --odometry"),
                                          (["--frames", "x", "--odometry", "o.csv", "--duration", "5"],
                                           "--duration is for --sim and --utias"),
                                          (["--frame-rate", "3"], "give the camera's 5 Hz divided by a whole number"),
                                          (["--utias", "log", "--frontend", "shipped-robot"],
                                           "a UTIAS log holds ranges and bearings already measured")])
def test_slam_command_refuses_bad_settings(argv, message, tmp_path, capsys):
    base = [] if "--frames" in argv or "--utias" in argv else ["--sim", "square"]
    assert main(["slam", *base, *argv, "--out", str(tmp_path / "o")]) == 2
    assert message in capsys.readouterr().err


@pytest.mark.parametrize("source", [["--sim", "square"], ["--utias", "log"]])
@pytest.mark.parametrize("duration", ["0", "-5"])
def test_a_duration_not_above_0_is_refused_before_anything_runs(source, duration, tmp_path, capsys):
    """``--duration 0`` ran the default walk or the whole log; on a log ``-5`` ended in an IndexError."""
    with pytest.raises(SystemExit) as exited:
        main(["slam", *source, "--duration", duration, "--out", str(tmp_path / "o")])
    assert exited.value.code == 2 and "give a number above 0" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_an_unreadable_model_is_refused_before_the_walk_is_rendered(tmp_path, capsys, monkeypatch):
    def no_rendering(*args, **kwargs):
        raise AssertionError("the walk was rendered before the model was opened")

    monkeypatch.setattr("detector.synth.walk.render_walk", no_rendering)
    model = tmp_path / "bad.onnx"
    model.write_text("not a model")
    assert main(["slam", "--sim", "square", "--frontend", str(model), "--out", str(tmp_path / "o")]) == 2
    assert "not a readable ONNX model" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_a_slower_frame_rate_hands_the_filter_fewer_sightings_of_the_same_walk(tmp_path):
    counts, odometry = {}, {}
    for rate in ("5", "1.25"):
        out = tmp_path / rate
        assert main(["slam", "--sim", "square", "--duration", "30", "--frame-rate", rate, "--out", str(out)]) == 0
        metrics = read_record(out / "metrics.json", "slam")
        counts[rate] = sum(metrics["counts"][key] for key in ("accepted", "rejected", "pending", "initialised"))
        odometry[rate] = metrics["odometry_error"]["mean"]
        assert metrics["sequence"] == f"sim square at {rate} frames/s"
    assert odometry["5"] == odometry["1.25"]  # the same walk
    assert 3 * counts["1.25"] < counts["5"] < 5 * counts["1.25"]  # about a quarter of the sightings


def _recording(folder, colour=(60, 120, 40)):
    """Three frames of a green floor (BGR ``colour``) and the odometry of the same seconds."""
    frames = folder / "frames"
    frames.mkdir()
    for t in (0.0, 0.5, 1.0):
        cv2.imwrite(str(frames / f"{t}.jpg"), np.full((240, 320, 3), colour, np.uint8))
    odometry = folder / "odometry.csv"
    odometry.write_text("t,x,y,theta\n0.0,0,0,0\n0.4,0.05,0,0\n0.8,0.1,0,0.02\n1.2,0.15,0,0.04\n")
    return frames, odometry


def test_a_recording_merges_frames_and_odometry_with_the_offset(tmp_path):
    frames, odometry = _recording(tmp_path)
    sequence = recorded_sequence(frames, odometry, COLOUR_FILTER, time_offset_s=0.3)
    assert [round(e.t, 2) for e in sequence.events if e.measurements is not None] == [0.3, 0.8, 1.3]
    assert sum(e.control is not None for e in sequence.events) == 3
    result = run_slam(sequence)
    assert np.allclose(result.poses[-1], [0.15, 0.0, 0.04], atol=1e-9)


@pytest.mark.parametrize("text, line", [("t,x,y,theta\n0.0,0,0,0\n0.4,far,0,0\n", 3),
                                        ("t,x,y,theta\n0.0,0,0,0\n\n\n0.4,far,0,0\n", 5)])
def test_a_recording_with_a_bad_odometry_line_is_named(tmp_path, text, line):
    """By the line an editor shows: blank lines count."""
    frames, odometry = _recording(tmp_path)
    odometry.write_text(text)
    with pytest.raises(ValueError, match=rf"odometry.csv:{line}: not finite numbers"):
        recorded_sequence(frames, odometry, COLOUR_FILTER, 0.3)


def test_a_recording_reads_odometry_written_with_spaces_after_the_commas(tmp_path):
    frames, odometry = _recording(tmp_path)
    plain = odometry.read_text()
    odometry.write_text(plain.replace(",", ", "))
    spaced = recorded_sequence(frames, odometry, COLOUR_FILTER, 0.3)
    odometry.write_text(plain)
    assert run_slam(spaced).poses.tolist() == \
        run_slam(recorded_sequence(frames, odometry, COLOUR_FILTER, 0.3)).poses.tolist()


def test_the_colour_filter_is_refused_a_calibration_without_a_colour_law_before_any_frame(tmp_path, capsys):
    """A box-only calibration (a model's, or one from before colour laws) cannot range the colour filter; leaving
    --calibration out uses the shipped colour law."""
    without_colour = tmp_path / "calibration.json"
    box_only = RangeCalibration(PowerLaw(50, -1), PowerLaw(220, -1))
    without_colour.write_text(json.dumps({"calibration": box_only.to_dict()}))
    assert main(["slam", "--sim", "square", "--frontend", "colour-filter", "--calibration", str(without_colour),
                 "--out", str(tmp_path / "slam")]) == 2
    assert "the calibration has none: leave the calibration out" in capsys.readouterr().err
    assert not (tmp_path / "slam").exists()


def test_a_recording_without_its_odometry_file_is_named(tmp_path):
    frames, odometry = _recording(tmp_path)
    odometry.unlink()
    with pytest.raises(ValueError, match=r"odometry.csv: no such odometry file - .* header t,x,y,theta"):
        recorded_sequence(frames, odometry, COLOUR_FILTER, 0.3)


def test_a_recording_hands_each_frame_the_camera_pose_of_the_nearest_odometry_row(tmp_path, monkeypatch):
    frames, odometry = _recording(tmp_path)
    odometry.write_text("t,x,y,theta,camera_height,camera_pitch,camera_roll\n0.0,0,0,0,0.50,0.10,0.00\n"
                        "0.4,0.05,0,0,0.51,0.12,0.01\n0.8,0.1,0,0.02,0.52,0.14,0.02\n1.2,0.15,0,0.04,0.53,0.16,0.03\n")
    seen = []
    monkeypatch.setattr(FrontEndSpec, "measurer", lambda self: lambda frame, pose=None: seen.append(pose) or [])
    recorded_sequence(frames, odometry, FrontEndSpec("shipped"), time_offset_s=0.3)
    assert [(p.z, p.pitch, p.roll) for p in seen] == [(0.51, 0.12, 0.01), (0.52, 0.14, 0.02), (0.53, 0.16, 0.03)]
    seen.clear()
    recorded_sequence(frames, odometry, FrontEndSpec("shipped"), time_offset_s=0.3, camera_pose=False)
    assert seen == [None, None, None]

    odometry.write_text(odometry.read_text().replace("0.8,0.1,0,0.02,0.52,0.14,0.02", "0.8,0.1,0,0.02,,,"))
    seen.clear()
    recorded_sequence(frames, odometry, FrontEndSpec("shipped"), time_offset_s=0.3)
    assert seen[1] is None and [(p.z, p.pitch, p.roll) for p in (seen[0], seen[2])] == [(0.51, 0.12, 0.01),
                                                                                       (0.53, 0.16, 0.03)]


@pytest.mark.parametrize("text, message", [
    ("t,x,y,theta,camera_height\n0.0,0,0,0,0.5\n1.2,0.1,0,0,0.5\n",
     "odometry.csv:1: camera_height without camera_pitch, camera_roll"),
    ("t,x,y,theta,camera_height,camera_pitch,camera_roll\n0.0,0,0,0,0.5,0.1,0\n1.2,0.1,0,0,-0.5,0.1,0\n",
     "odometry.csv:3: camera height -0.5 m.* - correct the row, or leave its three camera cells empty"),
    ("t,x,y,theta,camera_height,camera_pitch,camera_roll\n0.0,0,0,0,0.5,0.1,0\n1.2,0.1,0,0,0.5,,\n",
     "odometry.csv:3: not finite numbers in camera_height,camera_pitch,camera_roll")])
def test_a_recordings_camera_columns_are_all_or_none_and_each_pose_has_a_floor(tmp_path, text, message):
    """A lone camera_height column was ignored without a word; a height below the floor failed at its frame
    without naming the row."""
    frames, odometry = _recording(tmp_path)
    odometry.write_text(text)
    with pytest.raises(ValueError, match=message):
        recorded_sequence(frames, odometry, COLOUR_FILTER, 0.3)


def test_a_recording_without_truth_reports_what_it_saw(tmp_path, capsys):
    frames, odometry = _recording(tmp_path)
    assert main(["slam", "--frames", str(frames), "--odometry", str(odometry), "--frontend", "colour-filter",
                 "--out", str(tmp_path / "out")]) == 0
    assert "no truth to score against: 0 sightings accepted, 0 landmarks mapped; wrote" in capsys.readouterr().out


def test_a_recording_of_greyscale_frames_is_refused_it_holds_no_colour_to_name_a_pole(tmp_path, capsys):
    frames, odometry = _recording(tmp_path, colour=(90, 90, 90))
    assert main(["slam", "--frames", str(frames), "--odometry", str(odometry), "--frontend", "shipped-robot",
                 "--out", str(tmp_path / "out")]) == 2
    assert "every frame is greyscale" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_a_recording_says_which_frames_no_front_end_can_see_and_refuses_one_of_only_those(tmp_path, capsys):
    """One greyscale frame and one of 15x15 among three: each named with its count; the third is still measured.
    A recording of 15x15 frames alone is refused, not mapped as an empty field."""
    frames, odometry = _recording(tmp_path)
    cv2.imwrite(str(frames / "0.0.jpg"), np.full((240, 320, 3), 90, np.uint8))
    cv2.imwrite(str(frames / "0.5.jpg"), np.full((15, 15, 3), (60, 120, 40), np.uint8))
    sequence = recorded_sequence(frames, odometry, COLOUR_FILTER, 0.3)
    out = capsys.readouterr().out
    assert "1 of 3 frames are greyscale (0.0.jpg first)" in out
    assert "1 of 3 frames are smaller than 16 px a side (0.5.jpg first)" in out
    assert sum(e.measurements is not None for e in sequence.events) == 3
    cv2.imwrite(str(frames / "0.0.jpg"), np.full((15, 15, 3), (60, 120, 40), np.uint8))
    cv2.imwrite(str(frames / "1.0.jpg"), np.full((15, 15, 3), (60, 120, 40), np.uint8))
    with pytest.raises(ValueError, match="every frame is smaller than 16 px a side .* record the camera's full"):
        recorded_sequence(frames, odometry, COLOUR_FILTER, 0.3)


FIELD_MAP = "class,x,y\nbp,-4.675,3.175\ngp,0,3.175\nyp,4.675,3.175\npb,-4.675,-3.175\npg,0,-3.175\npy,4.675,-3.175\n"


def test_slam_with_a_map_localises_on_it_instead_of_building_one(tmp_path):
    """--map true: the walk's own map; a CSV of the same poles gives the same path; the map is not re-estimated."""
    paths = {}
    for name, source in (("true", "true"), ("csv", tmp_path / "field.csv")):
        (tmp_path / "field.csv").write_text(FIELD_MAP)
        out = tmp_path / name
        assert main(["slam", "--sim", "square", "--duration", "60", "--map", str(source), "--out", str(out)]) == 0
        metrics = read_record(out / "metrics.json", "slam")
        assert metrics["label"].startswith("EKF localisation on")
        assert "landmark_error" not in metrics and "phantoms" not in metrics
        assert metrics["robot_error"]["mean"] < 0.05 < 0.3 < metrics["odometry_error"]["mean"]  # here 0.019 / 0.416
        assert read_record(out / "map.json", "slam map")["landmarks"]["gp"] == [0.0, 3.175]
        paths[name] = (out / "path.csv").read_text()
    assert paths["true"] == paths["csv"]
    assert main(["slam", "--sim", "square", "--duration", "60", "--map", "true", "--eif",
                 "--out", str(tmp_path / "eif")]) == 0
    assert read_record(tmp_path / "eif" / "metrics.json", "slam")["label"] == "EIF localisation on the known map"


def test_a_start_given_off_the_true_one_is_recovered_when_its_uncertainty_is_said(tmp_path):
    """The square starts at (-1.2, -1.2, 0); a start 0.28 m and 0.2 rad off is found again with --start-std 0.2,0.2,
    and not when the filter is told it is known to a centimetre (over-confident, the gate then refuses the poles)."""
    errors = {}
    for std in ("0.2,0.2", "0.01,0.01"):
        out = tmp_path / std
        assert main(["slam", "--sim", "square", "--duration", "60", "--map", "true", "--start=-1.0,-1.4,0.2",
                     "--start-std", std, "--out", str(out)]) == 0
        path = np.loadtxt(out / "path.csv", delimiter=",", skiprows=1)
        assert path[0, 1:4] == pytest.approx([-1.0, -1.4, 0.2], abs=0.05)
        errors[std] = read_record(out / "metrics.json", "slam")["robot_error"]["mean"]
    assert errors["0.2,0.2"] < 0.1 < 0.5 < errors["0.01,0.01"]  # here 0.059 and 1.6 m


@pytest.mark.parametrize("text, message", [
    ("class,x,y\nbp,1,2\nblue,3,4\n", "map.csv:3: class 'blue' names no landmark"),
    ("class,x,y\nbp,1,2\nblue-pink,3,4\n", "map.csv:3: a second 'bp' pole"),
    ("class,x,y\nbp,1,two\n", "map.csv:2: x and y must be finite numbers"),
    ("class,x,y\nbp,1,nan\n", "map.csv:2: x and y must be finite numbers"),
    ("class,x\nbp,1\n", "map.csv:1: header must be class,x,y"),
    ("class,x,y\n", "map.csv: no poles"),
])
def test_a_bad_map_is_refused_by_its_line_before_anything_runs(text, message, tmp_path, capsys):
    (tmp_path / "map.csv").write_text(text)
    out = tmp_path / "o"
    assert main(["slam", "--sim", "square", "--map", str(tmp_path / "map.csv"), "--out", str(out)]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize("argv, message", [
    (["--map", "missing.csv"], "no such map file"),
    (["--eif"], "--eif is a localiser: give --map"),
    (["--map", "true", "--gate", "-1"], "must be a positive chi-square bound"),
])
def test_slam_refuses_bad_localisation_settings(argv, message, tmp_path, capsys):
    assert main(["slam", "--sim", "square", *argv, "--out", str(tmp_path / "o")]) == 2
    assert message in capsys.readouterr().err


@pytest.mark.parametrize("argv, message", [(["--start", "1,2"], "give X,Y,THETA as 3 numbers"),
                                          (["--start-std", "0.1,inf"], "give METRES,RADIANS as 2 positive"),
                                          (["--start-std", "0.1,0"], "give METRES,RADIANS as 2 positive")])
def test_slam_refuses_a_start_that_is_not_its_numbers(argv, message, tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["slam", "--sim", "square", *argv, "--out", str(tmp_path / "o")])
    assert exit_.value.code == 2 and message in capsys.readouterr().err


def test_map_true_needs_a_simulated_walk(tmp_path, capsys):
    frames, odometry = _recording(tmp_path)
    assert main(["slam", "--frames", str(frames), "--odometry", str(odometry), "--frontend", "shipped",
                 "--map", "true", "--out", str(tmp_path / "o")]) == 2
    assert "--map true is a simulated walk's own map" in capsys.readouterr().err
