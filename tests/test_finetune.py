"""`poles finetune`: a tiny rendered export goes through every stage to models, a report and a metrics file; the
paint measurement recovers a paint it was told; an export without a valid split is split; a rerun resumes; bad input
is refused with one message and nothing written into the export."""
from __future__ import annotations

import colorsys
import hashlib
import json
import re
import shutil
from dataclasses import replace
from pathlib import Path

import cv2
import pytest

from detector.cli import main
from detector.datasets.io import SplitCounts, load_dataset
from detector.evaluation.results import Counts, FrameCounts
from detector.finetune.blend import BlendScore, frame_errors, frames_against, pick_share
from detector.finetune.intake import prepare_dataset
from detector.finetune.budget import (CROP_EPOCH_PER_JUDGED_FRAME, MARGIN, MIN_TRAINING_S, PREPARING_SHARE,
                                     BudgetTooSmall, UnitCosts, machine_load, overrun_note, plan_job,
                                     replan_after_training, training_minutes)
from detector.finetune.pipeline import run_finetune
from detector.finetune.recipe import BLEND_SHARES, DEFAULT_BLEND_SHARE, FinetuneRecipe
from detector.finetune.results import FinetuneResult
from detector.formats import read_record
from detector.stages import StageFailed, StageLedger
from detector.synth.generate import SynthJob, generate_dataset
from detector.synth.scene import SceneConfig
from detector.synth.team_paint import TeamPaint, measure_team_paint
from naoslam.perception.two_stage import CropDetector
from naoslam.perception.yolo import LandmarkDetector
from naoslam.perception.loading import load_detector

#: A tiny recipe: 64 px, one augmented copy, a few seconds of training, 10-frame rendered sets.
#: Tiny settings: the epoch cap ends training long before the minutes, which the plan only has to fit in.
TINY = FinetuneRecipe(minutes=3, epochs=2, copies=1, imgsz=64, evaluation_frames=10)


def _digest(folder: Path) -> str:
    """One hash over every file's path and bytes under ``folder``."""
    digest = hashlib.sha256()
    for path in sorted(p for p in folder.rglob("*") if p.is_file()):
        digest.update(str(path.relative_to(folder)).encode() + path.read_bytes())
    return digest.hexdigest()


@pytest.fixture(scope="module")
def export(tmp_path_factory) -> Path:
    """A 16-frame rendered export at 640x480 (read-only)."""
    return generate_dataset(tmp_path_factory.mktemp("export") / "export", SynthJob(16, seed=21), workers=1,
                            progress=False)


@pytest.fixture(scope="module")
def finished(export, tmp_path_factory) -> tuple[Path, FinetuneResult, str]:
    """A whole tiny fine-tune of ``export``: its run folder, its results, and the export's digest before it ran."""
    before = _digest(export)
    out = tmp_path_factory.mktemp("finetune") / "run"
    return out, run_finetune(export, out, TINY), before


def test_finetune_writes_the_models_the_report_and_the_metrics_and_leaves_the_export_alone(export, finished):
    out, result, before = finished
    assert _digest(export) == before
    model = out / "models" / "poles-finetuned.onnx"
    detector = LandmarkDetector(model)
    # The shipped threshold rides along; the shipped calibration (measured at 640 px input) not at this test's 64 px.
    assert detector.stored_conf == LandmarkDetector().stored_conf and detector.calibration is None
    stages = result.stages
    assert stages.export.calibrated is False and stages.export.int8 == out / "models" / "poles-finetuned-int8.onnx"
    assert stages.export.int8.is_file() and stages.export.check.fp32_problems == ()
    assert FinetuneResult.from_json(read_record(out / "metrics.json", "finetune")) == result
    assert {row.set_name for row in stages.evaluate.rows} == {"your test frames", "rendered", "far poles"}
    assert {row.model for row in stages.evaluate.rows} == {"shipped", "fine-tune", f"blend {stages.blend.chosen:g}"}
    for row in stages.evaluate.rows:
        assert row.counts.tp + row.counts.fn > 0 and (row.model == "shipped") == (row.f1_change is None)
    page = (out / "report.html").read_text()
    assert "What the fine-tune changed" in page and "far poles" in page and "data:image/png;base64" in page
    assert stages.rehearsal.frames == stages.plan.rehearsal_frames == TINY.rehearsal_frames(
        stages.augment.train_images_out) > 0


def test_the_robot_model_is_fine_tuned_and_shipped_as_the_robot_model_is(export, tmp_path):
    from detector.model_files import ROBOT_WEIGHTS, read_info
    from naoslam.shipped import OPERATING_CONF_KEY, robot_path

    installed = sorted(ROBOT_WEIGHTS.parent.iterdir()) + sorted(robot_path().parent.iterdir())
    stages = run_finetune(export, tmp_path / "run", FinetuneRecipe(model="robot", minutes=2, epochs=2, copies=1,
                                                                   evaluation_frames=10)).stages
    assert sorted(ROBOT_WEIGHTS.parent.iterdir()) + sorted(robot_path().parent.iterdir()) == installed
    model = stages.export.fp32
    assert model.name == "poles-robot-finetuned.onnx" and stages.export.int8 is None
    shipped = read_info(robot_path()).extra
    assert read_info(model).extra[OPERATING_CONF_KEY] == shipped[OPERATING_CONF_KEY] == stages.evaluate.conf
    assert read_info(model).extra["calibration"] == shipped["calibration"]
    assert stages.train.epochs == 2 and [score.share for score in stages.blend.shares] == list(BLEND_SHARES)
    detector = load_detector(model)
    assert isinstance(detector, CropDetector) and detector.calibration is not None


def test_the_blend_ships_half_and_half_unless_its_valid_frames_show_another_share_better(finished):
    blend = finished[1].stages.blend
    shares = {score.share: score for score in blend.shares}
    assert list(shares) == list(BLEND_SHARES)
    for score in shares.values():
        assert (score.frames_better, score.frames_worse) == frames_against(
            score.frame_errors, shares[DEFAULT_BLEND_SHARE].frame_errors)
        assert sum(score.frame_errors.values()) == score.counts.fp + score.counts.fn
    assert blend.chosen == pick_share(list(shares.values())) and blend.weights.is_file()


def _share(share: float, f1: float, better: int, worse: int) -> BlendScore:
    return BlendScore(share, Counts(), 0.0, 0.0, f1, {}, better, worse)


@pytest.mark.parametrize("better, worse, chosen", [(1, 0, 0.5), (4, 0, 0.5), (5, 0, 1.0), (6, 1, 0.5), (7, 1, 1.0)])
def test_another_share_needs_a_sign_test_at_five_percent_over_the_frames_that_differ(better, worse, chosen):
    scores = [_share(0.5, 0.80, 0, 0), _share(1.0, 0.95, better, worse)]
    assert pick_share(scores) == chosen


def test_among_the_shares_that_pass_the_best_valid_f1_wins_and_a_broken_fine_tune_falls_back_to_the_shipped_model():
    assert pick_share([_share(0.0, 0.7, 0, 9), _share(0.5, 0.6, 0, 0), _share(0.75, 0.8, 6, 0),
                       _share(1.0, 0.9, 8, 0)]) == 1.0
    assert pick_share([_share(0.0, 0.9, 6, 0), _share(0.5, 0.5, 0, 0), _share(1.0, 0.2, 0, 6)]) == 0.0


def test_frames_are_counted_better_or_worse_by_their_errors():
    default = {"a.jpg": 1, "b.jpg": 0, "c.jpg": 2}
    assert frames_against({"a.jpg": 0, "b.jpg": 0, "c.jpg": 3}, default) == (1, 1)
    assert frame_errors((FrameCounts("a.jpg", Counts(tp=1, fp=1, fn=2)),)) == {"a.jpg": 3}


def test_a_rerun_skips_every_finished_stage_and_redoes_what_was_lost(export, finished, tmp_path):
    out, _, _ = finished
    copy = Path(shutil.copytree(out, tmp_path / "run", symlinks=True))
    shutil.rmtree(copy / "models")
    before = json.loads((copy / StageLedger.FILE_NAME).read_text())
    run_finetune(export, copy, TINY)
    after = json.loads((copy / StageLedger.FILE_NAME).read_text())
    assert after["train"] == before["train"]  # not trained again
    assert after["export"]["seconds"] != before["export"]["seconds"]
    assert (copy / "models" / "poles-finetuned.onnx").is_file()


def test_a_failed_stage_keeps_the_stages_before_it(export, tmp_path, monkeypatch):
    from detector.finetune import pipeline

    def refuse(*args, **kwargs):
        raise ValueError("no room")

    monkeypatch.setattr(pipeline, "_render_rehearsal", refuse)
    with pytest.raises(StageFailed, match="rehearsal"):
        run_finetune(export, tmp_path / "run", TINY)
    ledger = json.loads((tmp_path / "run" / StageLedger.FILE_NAME).read_text())
    assert ledger["augment"]["status"] == "done" and ledger["rehearsal"]["status"] == "failed"


def test_paint_from_recovers_a_paint_the_renderer_was_told(tmp_path):
    told = {"p": (0.80, 0.30, 0.45), "b": (0.20, 0.35, 0.75), "y": (0.85, 0.75, 0.20), "g": (0.12, 0.38, 0.22)}
    frames = generate_dataset(tmp_path / "painted", SynthJob(60, seed=5, config=SceneConfig(
        team_paint=tuple(sorted(told.items())))), progress=False)
    paint = measure_team_paint(frames)
    for letter, rgb in told.items():
        hue_told = colorsys.rgb_to_hsv(*rgb)[0] * 360
        assert paint.measured[letter] > 0
        assert abs((paint.hue_degrees(letter) - hue_told + 180) % 360 - 180) < 5, letter


def test_poles_synth_paint_from_writes_the_paint_it_measured(synth_dataset, tmp_path, capsys):
    assert main(["synth", "--out", str(tmp_path / "painted"), "--images", "4", "--paint-from", str(synth_dataset),
                 "--workers", "1"]) == 0
    paint = read_record(tmp_path / "painted" / "paint.json", "paint")
    generator = json.loads((tmp_path / "painted" / "annotations.json").read_text())["generator"]
    assert generator["team_paint"] == {letter: rgb for letter, rgb in paint["letters"].items()}
    assert "poles measured" in capsys.readouterr().out


def test_an_export_without_a_valid_split_is_split_from_its_train_frames(dataset_copy, tmp_path):
    for folder in ("images", "labels"):
        for path in (dataset_copy / "valid" / folder).iterdir():
            path.unlink()
    train = len(load_dataset(dataset_copy).split("train"))
    summary = prepare_dataset(dataset_copy, tmp_path / "prepared", None, seed=0)
    prepared = load_dataset(tmp_path / "prepared")
    assert summary.valid_made_from_train and summary.frames.valid == len(prepared.split("valid")) >= 1
    assert len(prepared.split("train")) + len(prepared.split("valid")) == train


def test_an_export_without_train_frames_is_refused_naming_it(dataset_copy, tmp_path, capsys):
    for folder in ("images", "labels"):
        for path in (dataset_copy / "train" / folder).iterdir():
            path.unlink()
    before = _digest(dataset_copy)
    assert main(["finetune", str(dataset_copy), "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err
    assert str(dataset_copy) in err and "poles split" in err and "Traceback" not in err
    assert _digest(dataset_copy) == before


def test_a_class_that_names_no_pole_is_refused_pointing_at_rename(dataset_copy, tmp_path, capsys):
    yaml = dataset_copy / "data.yaml"
    yaml.write_text(yaml.read_text().replace("'bp'", "'ball'"))
    assert main(["finetune", str(dataset_copy), "--out", str(tmp_path / "run")]) == 2
    assert "--rename" in capsys.readouterr().err


@pytest.mark.parametrize("out", ["inside", "file", "other"])
def test_an_out_folder_that_is_not_a_fine_tunes_is_refused(synth_dataset, tmp_path, out, capsys):
    target = {"inside": synth_dataset / "run", "file": tmp_path / "file", "other": tmp_path / "other"}[out]
    if out == "file":
        target.write_text("x")
    elif out == "other":
        target.mkdir()
        (target / "notes.txt").write_text("mine")
    assert main(["finetune", str(synth_dataset), "--out", str(target)]) == 2
    assert "--out" in capsys.readouterr().err
    assert not (synth_dataset / "run").exists()


def test_the_recipe_refuses_a_share_that_leaves_no_frame_of_yours_and_shares_the_minutes():
    with pytest.raises(ValueError, match="rehearsal-share"):
        FinetuneRecipe(rehearsal_share=1.0)
    assert FinetuneRecipe(rehearsal_share=0.5).rehearsal_frames(88) == 88
    assert FinetuneRecipe(rehearsal_share=0.0).rehearsal_frames(88) == 0


#: Unit costs of a two-core machine (seconds): decoding a frame, augmenting one, rendering one, judging one.
COSTS = UnitCosts(decode=0.006, augment=0.09, render=0.3, judge=0.18, workers=2)


@pytest.mark.parametrize("model", ["accurate", "robot"])
@pytest.mark.parametrize("minutes", [5, 15])
def test_the_plan_fits_a_large_export_into_its_minutes_with_less_work_that_scales(model, minutes):
    recipe = FinetuneRecipe(model=model, minutes=minutes)
    network = recipe.start.network
    large = plan_job(recipe, SplitCounts(1400, 200, 400), COSTS, network)
    small = plan_job(recipe, SplitCounts(10, 1, 3), COSTS, network)
    for plan in (large, small):
        assert sum(plan.seconds.values()) == pytest.approx(60 * minutes * (1 - MARGIN), abs=0.5)
        assert plan.seconds["train"] >= MIN_TRAINING_S[network]
    assert small.copies == recipe.copies
    assert small.evaluation_frames == (recipe.evaluation_frames if minutes == 15 else small.evaluation_frames)
    assert small.evaluation_frames <= recipe.evaluation_frames and not small.cuts[1:]
    assert large.copies < recipe.copies and large.rehearsal_frames < recipe.rehearsal_frames(1400 * 8)
    assert any("augmented copies of each of your 1,400 training frames, not 7" in cut for cut in large.cuts)
    assert large.evaluation_frames <= small.evaluation_frames
    assert large.blend_frames < 200 and any(f"on {large.blend_frames} of your 200 valid frames" in cut
                                            for cut in large.cuts)


def test_a_budget_below_the_least_work_is_refused_naming_the_smallest_that_plans():
    recipe = FinetuneRecipe(minutes=0.05)
    with pytest.raises(BudgetTooSmall, match=r"at least ([\d.]+) minutes") as refused:
        plan_job(recipe, SplitCounts(1400, 200, 400), COSTS, "yolo")
    smallest = float(re.search(r"at least ([\d.]+) minutes", str(refused.value)).group(1))
    plan = plan_job(FinetuneRecipe(minutes=smallest), SplitCounts(1400, 200, 400), COSTS, "yolo")
    assert plan.seconds["train"] >= MIN_TRAINING_S["yolo"]


def test_the_training_cap_leaves_what_the_later_stages_need():
    plan = plan_job(FinetuneRecipe(minutes=15), SplitCounts(10, 1, 3), COSTS, "yolo")
    later = (plan.seconds["training start"] + plan.after_training_seconds()) / 60
    assert training_minutes(plan, 1.0) == pytest.approx(15 * (1 - MARGIN) - 1.0 - later)
    assert training_minutes(plan, 60.0) == MIN_TRAINING_S["yolo"] / 60


def _after_training(plan, seconds_before: float) -> float:
    """What a job that followed ``plan`` up to the end of its training has spent, when that took ``seconds_before``."""
    return plan.seconds["start"] + seconds_before


@pytest.mark.parametrize("model", ["accurate", "robot"])
def test_a_late_training_or_a_slow_fine_tune_shrinks_the_judging_after_it(model):
    """On time and at the planned judging cost the re-plan keeps the plan's frames; a training that ran two minutes
    late, or a fine-tune that judges five times slower, cuts them, so blend, export and evaluate still fit."""
    recipe = FinetuneRecipe(model=model, minutes=15)
    frames = SplitCounts(1400, 200, 400)
    plan = plan_job(recipe, frames, COSTS, recipe.start.network)
    before = sum(plan.seconds.values()) - plan.after_training_seconds() - plan.seconds["start"]
    on_time = replan_after_training(plan, recipe, frames, _after_training(plan, before), COSTS.judge, 1.0)
    assert (on_time.evaluation_frames, on_time.held_out_frames, on_time.blend_frames) == \
        (plan.evaluation_frames, plan.held_out_frames, plan.blend_frames)
    for late, judge in ((120.0, COSTS.judge), (0.0, 5 * COSTS.judge)):
        spent = _after_training(plan, before + late)
        replan = replan_after_training(plan, recipe, frames, spent, judge, 1.0)
        assert replan.evaluation_frames < plan.evaluation_frames
        assert replan.blend_frames < (plan.blend_frames or frames.valid)
        assert spent + replan.after_training_seconds() <= 60 * 15
        assert any(f"each rendered set judged on {replan.evaluation_frames} frames" in cut for cut in replan.cuts)


def test_a_machine_that_ran_the_early_stages_slowly_slows_the_export_estimate():
    plan = plan_job(FinetuneRecipe(minutes=15), SplitCounts(1400, 200, 400), COSTS, "yolo")
    taken = {name: 3 * plan.seconds[name] for name in ("paint", "augment", "rehearsal")}
    assert machine_load(plan, taken) == pytest.approx(3.0)
    assert machine_load(plan, {name: 0.5 * plan.seconds[name] for name in taken}) == 1.0
    replan = replan_after_training(plan, FinetuneRecipe(minutes=15), SplitCounts(1400, 200, 400), 60.0, COSTS.judge,
                                   3.0)
    assert replan.seconds["export"] == pytest.approx(3 * plan.seconds["export"])


def test_a_budget_that_buys_less_than_one_pass_says_so_with_the_budget_that_buys_one():
    frames = SplitCounts(1566, 195, 196)  # the size of a real Roboflow export
    plan = plan_job(FinetuneRecipe(minutes=5), frames, COSTS, "yolo")
    warning = plan.short_of_an_epoch()
    assert warning and f"--minutes {plan.one_epoch_minutes:g} buys a whole pass" in warning
    enough = plan_job(FinetuneRecipe(minutes=plan.one_epoch_minutes), frames, COSTS, "yolo")
    assert enough.short_of_an_epoch() is None and enough.seconds["train"] >= enough.epoch_seconds
    half_a_minute_less = plan_job(FinetuneRecipe(minutes=plan.one_epoch_minutes - 0.5), frames, COSTS, "yolo")
    assert half_a_minute_less.short_of_an_epoch() is not None
    fewer = plan.one_epoch_minutes_without_copies
    assert fewer < plan.one_epoch_minutes and f"--minutes {fewer:g} with --copies 0" in warning
    assert plan_job(FinetuneRecipe(minutes=fewer, copies=0), frames, COSTS, "yolo").short_of_an_epoch() is None
    assert plan_job(FinetuneRecipe(minutes=fewer - 0.5, copies=0), frames, COSTS, "yolo").short_of_an_epoch()
    assert plan_job(FinetuneRecipe(model="robot", minutes=5), frames, COSTS, "crops").short_of_an_epoch() is None


def test_the_crop_networks_plan_gives_rehearsal_the_time_its_epoch_cap_leaves():
    """The robot model's 30 epochs take less than the training's share: the plan renders more rehearsal frames, as
    many as still leave the capped training its time; where the epochs need the whole share it keeps the share."""
    recipe = FinetuneRecipe(model="robot", minutes=10, copies=0, rehearsal_share=0.9)
    frames = SplitCounts(352, 88, 73)  # a 1,000-frame recording the teacher kept half of (the rendered venue)
    quick = UnitCosts(decode=0.002, augment=0.05, render=0.36, judge=0.007, workers=2)  # a two-core EPYC
    plan = plan_job(recipe, frames, quick, "crops")
    budget = 60 * 10 * (1 - MARGIN)
    training = 30 * (352 + plan.rehearsal_frames) * CROP_EPOCH_PER_JUDGED_FRAME * quick.judge
    assert plan.seconds["rehearsal"] > PREPARING_SHARE * budget
    assert training <= plan.seconds["train"] < training + 30 * CROP_EPOCH_PER_JUDGED_FRAME * quick.judge + 1
    assert plan.rehearsal_frames < recipe.rehearsal_frames(352)
    slow_epochs = plan_job(recipe, frames, replace(quick, judge=0.07), "crops")
    assert slow_epochs.seconds["rehearsal"] <= PREPARING_SHARE * budget < plan.seconds["rehearsal"]


def test_a_job_that_ran_late_says_by_how_much_and_which_stage():
    plan = plan_job(FinetuneRecipe(minutes=4), SplitCounts(10, 1, 3), COSTS, "yolo")
    kept = {"train": plan.planned("train"), "evaluate": plan.seconds["evaluate"]}
    assert overrun_note(plan, kept, 10.0) is None
    late = overrun_note(plan, {**kept, "evaluate": plan.seconds["evaluate"] + 150}, 10.0)
    assert late.startswith("this fine-tune took") and f"evaluate took {plan.seconds['evaluate'] + 150:.0f} s" in late


def test_each_starting_model_brings_its_measured_recipe_and_a_flag_overrides_it():
    robot = FinetuneRecipe(model="robot")
    assert (robot.rendered_share, robot.epoch_cap, robot.rehearsal_frames(88)) == (0.75, 30, 264)
    assert {"rehearsal_share": None, "rendered_share": 0.75, "epoch_cap": 30}.items() <= robot.settings().items()
    assert (FinetuneRecipe().rendered_share, FinetuneRecipe().epoch_cap) == (0.5, None)
    told = FinetuneRecipe(model="robot", rehearsal_share=0.0, epochs=5)
    assert (told.rendered_share, told.epoch_cap, told.rehearsal_frames(88)) == (0.0, 5, 0)
    with pytest.raises(ValueError, match="--epochs"):
        FinetuneRecipe(epochs=0)


def test_training_interrupted_after_an_epoch_resumes_from_it(export, tmp_path, monkeypatch):
    """Ctrl-C during training keeps the stages before it and the epochs done; the rerun continues from last.pt with
    what is left of the training's minutes."""
    from detector.training import train as training

    real_train, calls, hours = training._train, [], []

    def interrupted_after_one_epoch(model, tuner, **options):
        calls.append(options.get("resume", False))
        hours.append(options.get("time"))
        if len(calls) == 1:
            def stop(trainer):
                raise KeyboardInterrupt
            model.add_callback("on_model_save", stop)
        real_train(model, tuner, **options)

    monkeypatch.setattr(training, "_train", interrupted_after_one_epoch)
    with pytest.raises(KeyboardInterrupt):
        run_finetune(export, tmp_path / "run", TINY)
    assert (tmp_path / "run" / "train" / "weights" / "last.pt").is_file()
    result = run_finetune(export, tmp_path / "run", TINY)
    assert calls == [False, True]  # the second call resumed the first run
    assert hours[1] < hours[0]  # with what the first left of its budget
    assert result.stages.train.epochs >= 2 and (tmp_path / "run" / "models" / "poles-finetuned.onnx").is_file()


@pytest.mark.parametrize("model, training", [("robot", "the crop network's training starts again"),
                                              ("accurate", "the training resumes from its last epoch")])
def test_ctrl_c_in_a_fine_tune_says_what_a_rerun_resumes(export, tmp_path, monkeypatch, capsys, model, training):
    """The robot's crop network retrains on a rerun (it has no epochs to resume), the accurate model resumes: the
    interrupted command says which, and keeps its folder."""
    from detector.finetune import pipeline

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(pipeline, "prepare_dataset", interrupted)
    assert main(["finetune", str(export), "--out", str(tmp_path / "run"), "--model", model]) == 130
    message = capsys.readouterr().err
    assert f"the finished stages are kept in {tmp_path / 'run'}" in message and training in message


def test_a_square_export_is_warned_about_once_not_again_for_each_copy_the_fine_tune_makes(export, tmp_path,
                                                                                           monkeypatch, capsys):
    """The export, the run's copy of it and the augmented copy are all square: the user hears it once."""
    import cv2

    from detector.finetune import pipeline

    square = Path(shutil.copytree(export, tmp_path / "square"))
    for image in square.rglob("*.jpg"):
        cv2.imwrite(str(image), cv2.resize(cv2.imread(str(image)), (480, 480)))

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(pipeline, "_render_rehearsal", interrupted)
    assert main(["finetune", str(square), "--out", str(tmp_path / "run"), "--model", "robot"]) == 130
    assert capsys.readouterr().err.count("every image is square") == 1
    assert (tmp_path / "run" / "augmented" / "data.yaml").is_file()  # the copies were read and checked


@pytest.fixture(scope="module")
def unlabelled(export, tmp_path_factory) -> Path:
    """The export's frames without their labels: a team's recording."""
    folder = tmp_path_factory.mktemp("unlabelled") / "recording"
    folder.mkdir()
    for image in sorted(export.rglob("*.jpg")):
        shutil.copy(image, folder / image.name)
    return folder


def test_the_teacher_keeps_only_frames_it_is_sure_of_and_labels_its_sure_poles(unlabelled, tmp_path):
    from detector.finetune.teacher import FLOOR_CONF, teacher_labels
    from naoslam.perception.loading import load_detector

    sure = 0.7
    taught = teacher_labels(unlabelled, tmp_path / "taught", "shipped", sure, seconds=600, progress=False)
    detector = load_detector("shipped", conf=FLOOR_CONF)
    expected = {}
    for image in sorted(unlabelled.iterdir()):
        found = detector(cv2.imread(str(image)))
        if all(d.confidence >= sure for d in found):
            expected[image.name] = len(found)
    labelled = {sample.image.name: len(sample.instances) for sample in load_dataset(tmp_path / "taught").samples}
    assert labelled == expected and taught.kept == len(expected) and taught.stride == 1
    assert taught.unsure == taught.frames - taught.kept > 0 and taught.poles == sum(expected.values())
    assert taught.pole_free == sum(1 for count in expected.values() if count == 0)
    assert len(load_dataset(tmp_path / "taught").split("test")) == taught.test == taught.kept // 7


def test_the_robot_model_disputes_a_pole_the_teacher_names_otherwise_and_passes_one_named_alike(export):
    from detector.crops.samples import label_boxes
    from detector.finetune.teacher import names_otherwise
    from naoslam.perception.detections import Detection

    student = CropDetector("shipped-robot")
    agreed = 0
    for sample in load_dataset(export).samples:
        frame = cv2.imread(str(sample.image))
        for instance, box in zip(sample.instances, label_boxes(sample, frame.shape[1], frame.shape[0])):
            if names_otherwise(student, frame, [Detection.from_box(instance.cls, 0.9, box)]):
                continue  # the robot model names this labelled pole otherwise itself
            other = next(name for name in student.classes if name != instance.cls)
            assert names_otherwise(student, frame, [Detection.from_box(other, 0.9, box)])
            assert names_otherwise(student, frame, [Detection.from_box(instance.cls, 0.9, box),
                                                    Detection.from_box(other, 0.9, box)])
            agreed += 1
    assert agreed >= 5 and not names_otherwise(student, frame, [])


def test_a_frame_whose_pole_the_robot_model_names_otherwise_is_left_out_as_disputed(unlabelled, tmp_path,
                                                                                    monkeypatch):
    """A checker that disputes every pole (names_otherwise stubbed: the test above holds the real one) leaves only the
    pole-free frames, and counts the rest as disputed."""
    from detector.finetune import teacher

    alone = teacher.teacher_labels(unlabelled, tmp_path / "alone", "shipped", 0.7, seconds=600, progress=False)
    monkeypatch.setattr(teacher, "names_otherwise", lambda student, frame, found: bool(found))
    checked = teacher.teacher_labels(unlabelled, tmp_path / "checked", "shipped", 0.7, seconds=600,
                                     checker="shipped-robot", progress=False)
    pole_free = {s.image.name for s in load_dataset(tmp_path / "alone").samples if not s.instances}
    assert {s.image.name for s in load_dataset(tmp_path / "checked").samples} == pole_free
    assert alone.disputed == 0 and checked.disputed == alone.kept - alone.pole_free > 0
    assert checked.unsure == alone.unsure + checked.disputed and checked.poles == 0


def test_the_teacher_labels_every_so_many_frames_to_keep_to_its_seconds(unlabelled, tmp_path):
    from detector.finetune.teacher import TIMED_FRAMES, teacher_labels

    taught = teacher_labels(unlabelled, tmp_path / "taught", "shipped", 0.7, seconds=0.001, progress=False)
    assert taught.stride == taught.frames  # no time left after the timed frames: none of the rest
    assert taught.kept + taught.unsure == TIMED_FRAMES


def test_unlabelled_frames_alone_fine_tune_the_robot_model_and_the_report_says_what_they_added(unlabelled, tmp_path,
                                                                                               export):
    recipe = FinetuneRecipe(model="robot", minutes=2, epochs=2, copies=1, evaluation_frames=10,
                            unlabelled=str(unlabelled))
    stages = run_finetune(None, tmp_path / "run", recipe).stages
    assert stages.teacher is not None and stages.teacher.kept > 2
    assert stages.dataset.frames.train + stages.dataset.frames.valid + stages.dataset.frames.test == \
        stages.teacher.kept
    assert stages.plan.seconds["teacher"] > 0 and stages.export.fp32.is_file()
    report = (tmp_path / "run" / "report.html").read_text()
    assert "Unlabelled frames" in report and f"({stages.teacher.disputed}) where the robot model named" in report
    assert "Every 7th kept frame" in report and "{" not in report.split("Unlabelled frames")[1].split("</p>")[0]
    both = prepare_dataset(export, tmp_path / "both", {}, 0, more_train=tmp_path / "run" / "teacher")
    assert both.frames.train == len(load_dataset(export).split("train")) + stages.teacher.kept
    held_out = Path(shutil.copytree(export, tmp_path / "held-out"))  # a team that labelled only its test frames
    for split in ("train", "valid"):
        shutil.rmtree(held_out / split)
    only = prepare_dataset(held_out, tmp_path / "only", {}, 0, more_train=tmp_path / "run" / "teacher")
    assert only.frames.test == len(load_dataset(export).split("test")) and only.valid_made_from_train
    assert only.frames.train + only.frames.valid == stages.teacher.kept


@pytest.mark.parametrize("arguments, words", [
    (["--unlabelled", "FRAMES"], "--unlabelled teaches the robot model"),
    (["--model", "robot"], "nothing to fine-tune on"),
])
def test_unlabelled_frames_are_refused_where_they_cannot_teach(unlabelled, tmp_path, capsys, arguments, words):
    arguments = [str(unlabelled) if word == "FRAMES" else word for word in arguments]
    assert main(["finetune", "--out", str(tmp_path / "run"), *arguments]) == 2
    error = capsys.readouterr().err
    assert words in error and len(error.strip().splitlines()) == 1, error
    assert not (tmp_path / "run").exists()


def _magenta_frames(folder: Path) -> int:
    """Frames under ``folder`` whose median pixel is the magenta of the test backdrops (blue and red 2.5x green)."""
    import cv2
    import numpy as np

    medians = [np.median(cv2.imread(str(path)).reshape(-1, 3), axis=0) for path in sorted(folder.rglob("*.jpg"))]
    return sum(blue > 2.5 * green and red > 2.5 * green for blue, green, red in medians)


def test_rehearsal_frames_are_drawn_over_the_teams_own_backgrounds(tmp_path):
    """`--backgrounds`: the rehearsal frames stand over the team's frames without poles (a magenta field here), and
    over the renderer's rooms without it."""
    import cv2
    import numpy as np

    from detector.finetune.pipeline import _render_rehearsal
    from detector.synth.backdrops import scan_backdrops

    (tmp_path / "field").mkdir()
    for index in range(2):
        cv2.imwrite(str(tmp_path / "field" / f"empty{index}.png"), np.full((480, 640, 3), (200, 40, 160), np.uint8))
    paint = TeamPaint({"p": (0.9, 0.4, 0.6), "b": (0.3, 0.5, 0.7), "y": (1.0, 0.9, 0.5), "g": (0.3, 0.4, 0.3)}, {})
    recipe = FinetuneRecipe(backgrounds=str(tmp_path / "field"), backdrop_share=1.0)
    drawn = _render_rehearsal(tmp_path / "over", paint, 6, recipe, scan_backdrops(tmp_path / "field"))
    _render_rehearsal(tmp_path / "rooms", paint, 6, FinetuneRecipe(backdrop_share=1.0), ())
    assert drawn.backdrops == 2
    assert _magenta_frames(tmp_path / "over") >= 5 and _magenta_frames(tmp_path / "rooms") == 0


def test_a_backgrounds_folder_without_images_is_refused_before_anything_is_written(export, tmp_path, capsys):
    (tmp_path / "field").mkdir()
    (tmp_path / "field" / "notes.txt").write_text("no frames yet")
    before = _digest(export)
    assert main(["finetune", str(export), "--out", str(tmp_path / "run"), "--backgrounds",
                 str(tmp_path / "field")]) == 2
    error = capsys.readouterr().err
    assert f"--backgrounds {tmp_path / 'field'}: no images" in error and "Traceback" not in error
    assert not (tmp_path / "run").exists() and _digest(export) == before


def test_a_budget_too_small_is_refused_in_one_line_and_leaves_no_run_folder(export, tmp_path, capsys):
    assert main(["finetune", str(export), "--out", str(tmp_path / "run"), "--minutes", "0.05"]) == 2
    error = [line for line in capsys.readouterr().err.splitlines() if line.startswith("poles finetune:")]
    assert len(error) == 1 and "--minutes 0.05 is less than this fine-tune needs" in error[0], error
    assert re.search(r"give --minutes [\d.]+ or more", error[0]) and not (tmp_path / "run").exists()
