"""The demo: resumable stages, and the whole pipeline on a tiny budget producing a complete report."""
from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path

import pytest

from detector.formats import read_record
from detector.demo.budget import Budget
from detector.demo.pipeline import run_demo
from detector.demo.results import CheckSummary, DemoEvaluation, DemoSlam, DemoSpeed, EvaluatedFrontEnd
from detector.records import JsonRecord
from detector.stages import StageFailed, StageLedger, stage_key
from detector.training.summary import TrainingSummary
from naoslam.perception.yolo import LandmarkDetector

TINY = Budget("tiny", images=24, copies=1, models=("yolov8n-seg",), imgsz=64, epochs=1, train_hours=None, batch=8,
              export_hw=(96, 128), calibration_shots=18, walk_seconds=8.0, compare_seeds=1, conf=None)


@dataclass(frozen=True)
class Made(JsonRecord):
    """A stage's result in these tests: which call made it, and the file it wrote."""

    calls: int
    output: Path


def test_ledger_skips_done_stages_and_reruns_changed_ones(tmp_path):
    calls = []
    output = tmp_path / "out.txt"

    def work() -> Made:
        calls.append(1)
        output.write_text("x")
        return Made(len(calls), output)

    assert StageLedger(tmp_path).run("a", stage_key(x=1), [output], work, Made) == Made(1, output)
    assert StageLedger(tmp_path).run("a", stage_key(x=1), [output], work, Made) == Made(1, output)
    assert len(calls) == 1  # the second ledger read the first's result back, typed
    assert StageLedger(tmp_path).run("a", stage_key(x=2), [output], work, Made) == Made(2, output)
    output.unlink()
    assert StageLedger(tmp_path).run("a", stage_key(x=2), [output], work, Made) == Made(3, output)


def test_ledger_runs_again_a_stage_whose_recorded_result_is_of_another_shape(tmp_path):
    """A run folder from another version records a result its stage no longer returns: the stage runs again rather
    than hand on half a result."""
    output = tmp_path / "out.txt"
    output.write_text("x")
    StageLedger(tmp_path).run("a", "k", [output], lambda: CheckSummary(0, 2), CheckSummary)
    said = []
    rerun = StageLedger(tmp_path, announce=said.append).run("a", "k", [output], lambda: Made(7, output), Made)
    assert rerun == Made(7, output) and "does not fit its fields (calls, output), run again" in said[0]


def test_ledger_records_a_failure_and_keeps_earlier_stages(tmp_path):
    ledger = StageLedger(tmp_path)
    ledger.run("first", "k1", [], lambda: CheckSummary(0, 0), CheckSummary)
    with pytest.raises(StageFailed, match=r"stage 'second' failed: no frames"):
        ledger.run("second", "k2", [], lambda: (_ for _ in ()).throw(ValueError("no frames")), CheckSummary)
    saved = read_record(tmp_path / "stages.json", "stages")
    assert saved["first"]["status"] == "done" and saved["second"]["status"] == "failed"
    assert "no frames" in saved["second"]["error"]


def test_demo_runs_every_stage_writes_the_report_and_resumes(tmp_path, monkeypatch):
    out = tmp_path / "demo"
    assert run_demo(out, TINY) == 0
    stages = read_record(out / "stages.json", "stages")
    assert list(stages) == ["data", "check", "augment", "train yolov8n-seg", "export yolov8n-seg", "calibrate",
                            "evaluate", "slam", "speed"]
    assert all(s["status"] == "done" for s in stages.values())
    # Two validation frames are too few poles to choose a threshold on: the shipped model's own stays.
    evaluated = DemoEvaluation.from_json(stages["evaluate"]["summary"])
    assert evaluated.conf_source.startswith("the shipped model's")
    assert evaluated.conf == LandmarkDetector().stored_conf
    page = (out / "report.html").read_text()
    for heading in ("Stages and time taken", "Dataset and augmentation", "Training", "Export and agreement",
                    "Range calibration", "Evaluation on held-out frames", "EKF SLAM on a simulated walk",
                    "Speed on the robot"):
        assert heading in page
    assert "A square walk of 8 seconds" in page  # the walk it ran
    assert len(re.findall(r'src="data:image/(?:png|jpeg);base64,', page)) >= 10
    assert "not produced" not in page.split("Evaluation on held-out frames")[0]
    assert page.count('alt="confusion matrix"') == 6  # one per front end
    assert page.count('alt="recall by pole width"') == 6
    written = [EvaluatedFrontEnd.from_json(row) for row in
               read_record(out / "evaluation" / "summary.json", "demo evaluation")["rows"]]
    assert written == list(evaluated.front_ends)
    assert [row.evaluation.model for row in written] == ["yolov8n-seg.onnx", "yolov8n-seg-int8.onnx",
                                                         "shipped", "colour-filter", "yolov8n-seg.onnx (boxes, pose)",
                                                         "shipped-robot (boxes, pose)"]
    # The robot front end beside the trained model: the same frames, each with its pose, both matched by box.
    boxed = {row.evaluation.model: row.evaluation for row in written if "(boxes, pose)" in row.evaluation.model}
    assert all(e.matching == "box" and e.camera_poses >= e.images for e in boxed.values())
    robot = boxed["shipped-robot (boxes, pose)"]
    assert 0 <= robot.precision <= 1 and robot.f1 is not None and f"{robot.f1:.3f}" in page
    slam = DemoSlam.from_json(stages["slam"]["summary"])
    assert [run.front_end for run in slam.runs] == ["model", "robot front end", "colour filter"]
    speed = DemoSpeed.from_json(stages["speed"]["summary"])
    assert [row.front_end for row in speed.rows] == ["accurate model, INT8", "robot front end"]
    for row in speed.rows:
        assert (row.capped_ms is not None and row.capped_ms > 0) or "not timed" in row.note
        assert row.uncapped_ms is not None and row.uncapped_ms > 0
    # The shipped model as installed is counted beside the trained one, and the report says what training bought.
    f1 = {row.evaluation.model: row.evaluation.f1 for row in written}
    gain = evaluated.against_shipped
    assert gain.model == "yolov8n-seg.onnx" and gain.reference == "shipped"
    assert gain.change.difference == pytest.approx(f1["yolov8n-seg.onnx"] - f1["shipped"])
    assert gain.change.low <= gain.change.difference <= gain.change.high
    assert gain.reference_conf == LandmarkDetector().stored_conf
    assert f"changes F1 by {gain.change.difference:+.3f}" in page
    # A second run finds every stage up to date and redoes nothing.
    before = {k: v["seconds"] for k, v in stages.items()}
    assert run_demo(out, TINY) == 0
    after = read_record(out / "stages.json", "stages")
    assert {k: v["seconds"] for k, v in after.items()} == before
    # A new starting checkpoint (an updated package ships other weights) makes training, and all after it, run again.
    monkeypatch.setattr("detector.demo.pipeline._start_weights", lambda model: None)
    stale = out / "evaluation" / "colour-filter" / "errors" / "from-the-last-model.jpg"
    stale.write_bytes(b"an overlay of the model before")
    assert run_demo(out, TINY) == 0
    assert not stale.exists()  # a stage that runs again replaces its folder whole
    again = read_record(out / "stages.json", "stages")
    assert TrainingSummary.from_json(again["train yolov8n-seg"]["summary"]).started_from is None
    assert DemoEvaluation.from_json(again["evaluate"]["summary"]).conf_source == "best F1 on the validation split"
    assert TrainingSummary.from_json(stages["train yolov8n-seg"]["summary"]).started_from.name == "poles-yolov8n-seg.pt"
    assert {k for k in again if again[k]["seconds"] != before[k]} >= {"train yolov8n-seg", "export yolov8n-seg"}


def test_the_demo_refuses_a_folder_of_someone_elses_files(tmp_path):
    """`poles demo --out ~/thesis` wrote data/, augmented/, train/ and stages.json among the files there."""
    mine = tmp_path / "thesis"
    mine.mkdir()
    (mine / "thesis.tex").write_text("three years")
    (tmp_path / "notes.txt").write_text("a file")
    for out, said in ((mine, "holds thesis.tex, not an earlier demo's"), (tmp_path / "notes.txt", "is a file")):
        with pytest.raises(ValueError, match=said):
            run_demo(out, TINY)
    assert sorted(p.name for p in mine.iterdir()) == ["thesis.tex"]
    assert (mine / "thesis.tex").read_text() == "three years"


def test_the_fast_demo_trains_for_what_the_other_stages_leave_of_its_whole_time():
    """On the test machine the whole run fits 12 minutes; a machine twice as slow before training trains for less,
    so that it ends near the same time; the slowest still trains for a couple of minutes."""
    from detector.demo.budget import AFTER_TRAINING_S, BEFORE_TRAINING_S, BUDGETS, MIN_TRAINING_S

    fast = BUDGETS["fast"]
    here, twice_as_slow = fast.training_hours(BEFORE_TRAINING_S), fast.training_hours(2 * BEFORE_TRAINING_S)
    assert 3600 * here + BEFORE_TRAINING_S + AFTER_TRAINING_S == pytest.approx(60 * fast.whole_minutes)
    assert 3600 * twice_as_slow + 2 * (BEFORE_TRAINING_S + AFTER_TRAINING_S) == pytest.approx(60 * fast.whole_minutes)
    assert twice_as_slow < here <= fast.train_hours
    assert fast.training_hours(3600) * 3600 == pytest.approx(MIN_TRAINING_S)
    assert TINY.training_hours(1000) is None  # a budget without a whole time trains for its epochs


def test_a_demo_whose_training_ran_late_cuts_the_stages_after_it_and_one_on_time_keeps_them():
    """On pace the stages after the export keep every shot, walk second and seed; a training that ran five minutes
    past its plan leaves less, and the shots, the walk and the seeds shrink, never under their least, with a line
    that says what was cut."""
    from detector.demo.budget import (AFTER_EXPORT_SHARE, BEFORE_TRAINING_S, BUDGETS, MIN_CALIBRATION_SHOTS,
                                      MIN_COMPARE_SEEDS, MIN_WALK_S)

    fast = BUDGETS["fast"]
    on_pace = 60 * fast.whole_minutes - AFTER_EXPORT_SHARE * fast.after_training_s(BEFORE_TRAINING_S)
    assert fast.after_export(on_pace, BEFORE_TRAINING_S) == (fast, None)
    late, said = fast.after_export(on_pace + 60, BEFORE_TRAINING_S)
    assert MIN_CALIBRATION_SHOTS < late.calibration_shots < fast.calibration_shots
    assert MIN_WALK_S < late.walk_seconds < fast.walk_seconds and late.compare_seeds <= fast.compare_seeds
    assert f"{late.calibration_shots} calibration shots (not {fast.calibration_shots})" in said
    hopeless, _ = fast.after_export(60 * fast.whole_minutes + 300, BEFORE_TRAINING_S)
    assert (hopeless.calibration_shots, hopeless.walk_seconds, hopeless.compare_seeds) == (
        MIN_CALIBRATION_SHOTS, MIN_WALK_S, MIN_COMPARE_SEEDS)
    assert TINY.after_export(10_000, 1.0) == (TINY, None)  # a budget without a whole time does all it planned


def test_a_demo_that_ran_late_says_by_how_much_and_where():
    from detector.demo.budget import BEFORE_TRAINING_S, BUDGETS
    from detector.demo.pipeline import late_demo_note
    from detector.stages import StageRecord

    fast = BUDGETS["fast"]
    cap_s = 3600 * fast.training_hours(BEFORE_TRAINING_S)
    timings = [StageRecord("data", "k", "done", BEFORE_TRAINING_S),
               StageRecord("train yolov8n-seg", "k", "done", cap_s),
               StageRecord("slam", "k", "done", 150.0), StageRecord("reused", "k", "done", 900.0, ran=False)]
    assert late_demo_note(fast, timings, 60 * fast.whole_minutes) is None
    slow = [*timings[:2], StageRecord("slam", "k", "done", 600.0)]
    said = late_demo_note(fast, slow, BEFORE_TRAINING_S + cap_s + 600.0)
    assert said.startswith("this demo took") and "the stages after training took 600 s" in said
    assert late_demo_note(TINY, slow, 10_000.0) is None


def test_the_demo_s_minutes_set_its_whole_time_and_too_few_are_refused():
    from detector.demo.budget import BUDGETS

    fast = BUDGETS["fast"]
    assert fast.with_minutes(20).whole_minutes == 20
    assert fast.with_minutes(20).training_hours(34.0) > fast.training_hours(34.0)
    with pytest.raises(ValueError, match=f"at least {fast.smallest_minutes():g} minutes"):
        fast.with_minutes(fast.smallest_minutes() - 0.5)
    with pytest.raises(ValueError, match="trains for its 200 epochs"):
        BUDGETS["full"].with_minutes(60)
