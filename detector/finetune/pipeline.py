"""``poles finetune EXPORT --out RUN``: a team's annotated export to a deployable model, stage by stage, resumable.

dataset (check, split) -> paint (measured on the team's poles) -> augment (the thesis's operations) -> rehearsal
(rendered frames in that paint) -> mix -> train (from the shipped checkpoint, time-capped) -> blend (share chosen on
the valid split) -> export (FP32 + INT8, the shipped calibration and threshold) -> evaluate (shipped, fine-tune and
blend on the held-out frames and on fresh rendered sets) -> report. Each stage hands on a typed result
(``finetune.results``).
"""
from __future__ import annotations

import shutil
import time
from collections.abc import Callable
from pathlib import Path

import cv2

from augment.run import AugmentSummary, augment_dataset, augment_once
from detector.console import make_console
from detector.datasets.intake import each_warning_once
from detector.datasets.io import DatasetWriter, SplitCounts, load_dataset
from detector.datasets.model import BAD_INPUT_ERRORS
from detector.errors import keep_on_interrupt
from detector.evaluation.paired import REFERENCE
from detector.evaluation.predictors import Predictor, TorchPredictor
from detector.finetune import crop_network
from detector.finetune.blend import BlendChoice, choose_blend
from detector.finetune.budget import (TEACHING_SHARE, BudgetTooSmall, JobPlan, describe, judging_seconds,
                                     machine_load, measure_costs, overrun_note, plan_job, replan_after_training,
                                     training_minutes)
from detector.finetune.intake import DatasetIntake, prepare_dataset
from detector.finetune.judge import RENDERED_SETS, Judgement, compare_models, render_set
from detector.finetune.recipe import DEFAULT_BLEND_SHARE, SIGN_TEST_LEVEL, FinetuneRecipe
from detector.finetune.report import write_report
from detector.finetune.results import ExportedModel, FinetuneResult, FinetuneStages, RehearsalSummary
from detector.finetune.teacher import SHIPPED_SURE_CONF, TeacherLabels, teacher_labels
from detector.formats import write_record
from detector.model_files import add_metadata, read_checkpoint, read_info
from detector.outputs import check_placement
from detector.parallel import default_workers
from detector.stages import StageFailed, StageLedger, file_fingerprint, stage_key
from detector.synth.backdrops import scan_backdrops
from detector.synth.generate import SynthJob, generate_dataset, render_one
from detector.synth.scene import SceneConfig
from detector.synth.team_paint import MIN_PART_PIXELS, NoPaintMeasured, TeamPaint, measure_team_paint
from detector.training.soup import blend_checkpoints
from detector.training.summary import TrainingSummary
from detector.training.train import TrainSettings, summarise_run, train_model, trained_minutes
from export.onnx_export import int8_path
from export.run import ExportJob, run_export
from naoslam.shipped import OPERATING_CONF_KEY, resolve_model

console = make_console()


def run_finetune(annotated: Path | None, out: Path, recipe: FinetuneRecipe,
                 renames: dict[str, str] | None = None) -> FinetuneResult:
    """Run every stage into ``out`` (an earlier fine-tune's folder resumes it); returns every stage's result.
    ``annotated`` may be None where ``recipe.unlabelled`` gives the frames (the teacher labels them all).
    Raises ``StageFailed`` naming the stage that failed (everything before it stays)."""
    if annotated is None and recipe.unlabelled is None:
        raise ValueError("nothing to fine-tune on: give your annotated export, or --unlabelled FRAMES with --model "
                         "robot, or both")
    annotated, out = (Path(annotated) if annotated is not None else None), Path(out)
    unlabelled = Path(recipe.unlabelled) if recipe.unlabelled else None
    for given in (annotated, unlabelled):
        if given is not None:
            _check_run_folder(out, given)
    backdrops = scan_backdrops(Path(recipe.backgrounds)) if recipe.backgrounds else ()
    new_folder = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    ledger = StageLedger(out, announce=lambda text: console.rule(f"[bold]{text}", align="left"))
    keep_on_interrupt(_resume_note(out, recipe))
    sources = " and ".join(str(given) for given in (annotated, unlabelled) if given is not None)
    console.print(f"[bold]poles finetune[/bold] {sources} into {out}: the shipped {recipe.model} model, "
                  f"{recipe.minutes:g} minutes in all")
    start = time.perf_counter()
    try:
        with each_warning_once():  # the export's warnings, not once more for each of the run's copies of it
            stages = _stages(ledger, annotated, out, recipe, renames or {}, backdrops)
    except StageFailed as failure:
        too_small = isinstance(failure.__cause__, BudgetTooSmall)
        if new_folder and (too_small or not any(record.status == "done" for record in ledger.records.values())):
            shutil.rmtree(out, ignore_errors=True)  # refused before anything was made: leave nothing behind
        if too_small:
            raise failure.__cause__ from None  # one line: the smallest --minutes that works here
        raise
    result = FinetuneResult(recipe, stages,
                            seconds={record.name: round(record.seconds, 1) for record in ledger.timings()},
                            wall_seconds_this_call=round(time.perf_counter() - start, 1), report=out / "report.html")
    write_report(result, ledger.timings())
    write_record(out / "metrics.json", "finetune", result.to_json())
    ran = sum(record.seconds for record in ledger.timings() if record.ran)
    late = overrun_note(stages.replan, {record.name: record.seconds for record in ledger.timings()},
                        time.perf_counter() - start - ran)
    if late:
        console.print(f"[yellow]{late}")
    return result


def _resume_note(out: Path, recipe: FinetuneRecipe) -> str:
    """What an interrupted fine-tune keeps, as a rerun will find it: the accurate model's training resumes from its
    last epoch, the robot's crop network (a minute or two) trains again."""
    training = ("the crop network's training starts again (it takes a minute or two)" if recipe.start.network == "crops"
                else "the training resumes from its last epoch")
    return (f"the finished stages are kept in {out}: run the same command again to go on from the stage that stopped, "
            f"within what is left of --minutes; {training}")


def _check_run_folder(out: Path, annotated: Path) -> None:
    """Refuse an ``out`` that overlaps the annotated export (any folder it is read from) or lies inside a dataset, or
    is not a new, empty or earlier fine-tune's folder."""
    try:
        inputs = load_dataset(annotated).input_folders()
    except BAD_INPUT_ERRORS:  # the dataset stage says what is wrong with it
        inputs = (annotated,)
    check_placement(out, (annotated, *inputs))
    StageLedger.check_folder(out, "fine-tune")


def _dataset_fingerprint(annotated: Path) -> str:
    """Names, sizes and times of every file in the annotated export (or of a video): a changed one reruns every
    stage."""
    files = [annotated] if annotated.is_file() else sorted(p for p in annotated.rglob("*") if p.is_file())
    return stage_key(files=[(p.name if p == annotated else str(p.relative_to(annotated)), p.stat().st_size,
                             p.stat().st_mtime_ns) for p in files])


def _stages(ledger: StageLedger, annotated: Path | None, out: Path, recipe: FinetuneRecipe, renames: dict[str, str],
            backdrops: tuple[Path, ...]) -> FinetuneStages:
    data, augmented, rehearsal, mixed = (out / name for name in ("dataset", "augmented", "rehearsal", "mixed"))
    taught, teacher_key, labelled = None, None, out / "teacher"
    if recipe.unlabelled:
        unlabelled = Path(recipe.unlabelled)
        checker = recipe.start.shipped  # the robot model the frames teach checks the teacher's classes
        teacher_key = stage_key(frames=_dataset_fingerprint(unlabelled), teacher=recipe.teacher,
                                model=file_fingerprint(resolve_model(recipe.teacher)),
                                checker=file_fingerprint(resolve_model(checker)))
        seconds = 60 * recipe.minutes * TEACHING_SHARE
        taught = ledger.run("teacher", teacher_key, [labelled / "data.yaml"],
                            lambda: _teach(unlabelled, labelled, recipe.teacher, checker, seconds), TeacherLabels)
    key = stage_key(dataset=_dataset_fingerprint(annotated) if annotated else None, teacher=teacher_key,
                    renames=renames, seed=recipe.seed)
    source = annotated or labelled
    more = labelled if annotated and taught else None
    intake = ledger.run("dataset", key, [data / "data.yaml"],
                        lambda: prepare_dataset(source, data, renames, recipe.seed, more), DatasetIntake)
    plan_key = stage_key(dataset=key, recipe=recipe.settings(), backdrops=len(backdrops))
    taught_s = ledger.records["teacher"].seconds if taught else 0.0
    plan = ledger.run("plan", plan_key, [], lambda: _plan(data, recipe, backdrops, taught_s), JobPlan)
    console.print(describe(plan))
    for cut in plan.cuts:
        console.print(f"  {cut}")
    if plan.short_of_an_epoch():
        console.print(f"[yellow]{plan.short_of_an_epoch()}")
    paint_key = stage_key(dataset=key)
    paint = ledger.run("paint", paint_key, [out / "paint.json"],
                       lambda: _measure_paint(data, out, annotated or Path(recipe.unlabelled)), TeamPaint)
    augment_key = stage_key(dataset=key, copies=plan.copies)
    augment = ledger.run("augment", augment_key, [augmented / "data.yaml"], lambda: augment_dataset(
        data, augmented, copies=plan.copies, seed=recipe.seed, preview=True, force=True), AugmentSummary)
    frames = plan.rehearsal_frames
    rehearsal_key = stage_key(paint=paint_key, frames=frames, far=recipe.far_share, own=recipe.own_paint_share,
                              backdrops=[str(path) for path in backdrops], backdrop_share=recipe.backdrop_share)
    rendered = ledger.run("rehearsal", rehearsal_key, [rehearsal / "data.yaml"] if frames else [],
                          lambda: _render_rehearsal(rehearsal, paint, frames, recipe, backdrops), RehearsalSummary)
    mix_key = stage_key(augment=augment_key, rehearsal=rehearsal_key, valid=plan.blend_frames)
    mix = ledger.run("mix", mix_key, [mixed / "data.yaml"],
                     lambda: _mix(augmented, rehearsal if frames else None, mixed, plan.blend_frames), SplitCounts)
    training = {k: v for k, v in recipe.settings().items() if k != "evaluation_frames"}
    train_key = stage_key(mix=mix_key, recipe=training, start=file_fingerprint(recipe.start.weights))
    spent = sum(record.seconds for record in ledger.timings()) / 60
    run = out / "train"
    trained = run / ("poles-robot.pt" if recipe.start.network == "crops" else "weights/last.pt")
    train = ledger.run("train", train_key, [trained], lambda: _train(train_key, mixed, run, recipe, plan, spent),
                       TrainingSummary)
    replan = ledger.run("replan", stage_key(train=train_key, plan=plan_key), [],
                        lambda: _replan(plan, data, trained, recipe, ledger), JobPlan)
    conf = float(_starting_metadata(recipe)[OPERATING_CONF_KEY])
    blend_key = stage_key(train=train_key, conf=conf, default_share=DEFAULT_BLEND_SHARE, level=SIGN_TEST_LEVEL,
                          frames=replan.blend_frames)
    blend = ledger.run("blend", blend_key, [out / "blend"],
                       lambda: _blend(trained, data, out / "blend", conf, recipe, replan.blend_frames), BlendChoice)
    export_key = stage_key(blend=blend_key)
    model = out / "models" / recipe.start.finetuned_name
    exported = ledger.run("export", export_key, [model],
                          lambda: _export_model(blend.weights, model, data, mixed, recipe), ExportedModel)
    evaluate_key = stage_key(export=export_key, frames=replan.evaluation_frames, held_out=replan.held_out_frames,
                             sets=RENDERED_SETS)
    judgement = ledger.run("evaluate", evaluate_key, [out / "evaluation" / "summary.json"], lambda: _evaluate(
        out / "evaluation", data, trained, blend, conf, recipe, replan), Judgement)
    return FinetuneStages(taught, intake, plan, paint, augment, rendered, mix, train, replan, blend, exported,
                          judgement)


def _plan(data: Path, recipe: FinetuneRecipe, backdrops: tuple[Path, ...], taught_s: float) -> JobPlan:
    """The work fitted to ``recipe.minutes`` less the teacher's ``taught_s``, from this machine's speed at each kind
    of work on the team's frames."""
    dataset = load_dataset(data)
    samples = [sample for split in ("train", "valid") for sample in dataset.split(split)]
    job = SynthJob(1, recipe.seed + 7000, config=SceneConfig(far_share=recipe.far_share), backgrounds=backdrops,
                   backdrop_share=recipe.backdrop_share)
    predictor = judging_predictor(recipe)(recipe.start.weights)
    costs = measure_costs(samples, lambda: render_one(job, 0), predictor, augment_once, default_workers(1000))
    frames = SplitCounts(*(len(dataset.split(split)) for split in ("train", "valid", "test")))
    return plan_job(recipe, frames, costs, recipe.start.network, taught_s)


def _teach(unlabelled: Path, folder: Path, teacher: str, checker: str, seconds: float) -> TeacherLabels:
    """The unlabelled frames labelled by ``teacher`` where it is sure (the shipped model at the threshold of its 95 %
    precision, another at its own threshold) and ``checker`` names its poles alike, in about ``seconds``; refused
    when it is sure of too few."""
    taught = teacher_labels(unlabelled, folder, teacher, SHIPPED_SURE_CONF if teacher == "shipped" else None, seconds,
                            checker)
    every = f", one in {taught.stride} to keep to --minutes" if taught.stride > 1 else ""
    console.print(f"the teacher labelled {taught.kept} of {taught.frames} frames{every} ({taught.poles} poles, "
                  f"{taught.pole_free} without; {taught.unsure} left out where it was unsure, {taught.disputed} of "
                  f"them where the robot model named a pole otherwise), {taught.test} held out")
    if taught.kept - taught.test < 2:
        raise ValueError(f"{unlabelled}: the teacher is sure of {taught.kept} of its {taught.frames} frames, too few "
                         "to train on - record more frames, or label some and pass them as the export")
    return taught


def _replan(plan: JobPlan, data: Path, trained: Path, recipe: FinetuneRecipe, ledger: StageLedger) -> JobPlan:
    """The stages after training fitted to what is left of the minutes, judging timed with the fine-tuned model on
    the team's held-out frames and the machine's load read from the stages before; says what it cut."""
    dataset = load_dataset(data)
    held_out = dataset.split("test") or dataset.split("valid")
    frames = [cv2.imread(str(sample.image)) for sample in held_out[:4]]
    judge_s = judging_seconds(judging_predictor(recipe)(trained), frames) + plan.costs.decode
    taken = {record.name: record.seconds for record in ledger.timings()}
    load = machine_load(plan, taken)
    counts = SplitCounts(*(len(dataset.split(split)) for split in ("train", "valid", "test")))
    spent = sum(taken.values()) + plan.seconds["start"]
    replan = replan_after_training(plan, recipe, counts, spent, judge_s, load)
    console.print(f"{spent / 60:.1f} of {plan.minutes:g} minutes spent; judging the fine-tune takes {judge_s:.2f} s a "
                  f"frame ({plan.costs.judge:.2f} planned), the stages before ran {load:.1f}x their plan")
    held_out_all, valid_all = counts.test or counts.valid, counts.valid
    for what, before, after in (("frames per rendered judging set", plan.evaluation_frames, replan.evaluation_frames),
                                ("held-out frames judged", plan.held_out_frames or held_out_all,
                                 replan.held_out_frames or held_out_all),
                                ("valid frames each blend is scored on", plan.blend_frames or valid_all,
                                 replan.blend_frames or valid_all)):
        if after < before:
            console.print(f"  {after} {what}, not {before}, to keep to --minutes")
    return replan


def _measure_paint(data: Path, out: Path, annotated: Path) -> TeamPaint:
    """The team's paint, measured on its copy of the export; refused in the export's own name."""
    try:
        paint = measure_team_paint(data)
    except NoPaintMeasured:
        raise ValueError(f"{annotated}: no annotated pole is large enough to measure its paint (each band needs "
                         f"{MIN_PART_PIXELS} pixels) - a fine-tune learns your poles from your frames: annotate the "
                         "poles in them, some near the camera") from None
    write_record(out / "paint.json", "paint", paint.to_json())
    return paint


def _render_rehearsal(folder: Path, paint: TeamPaint, frames: int, recipe: FinetuneRecipe,
                      backdrops: tuple[Path, ...]) -> RehearsalSummary:
    """Render the rehearsal frames, ``own_paint_share`` of them in the team's paint and ``backdrop_share`` over
    ``backdrops`` when there are any; none (and the folder removed) when the recipe mixes none."""
    if not frames:
        shutil.rmtree(folder, ignore_errors=True)
        return RehearsalSummary(0)
    config = SceneConfig(team_paint=paint.scene_paint(), team_paint_share=recipe.own_paint_share,
                         far_share=recipe.far_share)
    job = SynthJob(frames, recipe.seed + 7001, config=config, backgrounds=backdrops,
                   backdrop_share=recipe.backdrop_share)
    protect = (Path(recipe.backgrounds),) if recipe.backgrounds else ()
    generate_dataset(folder, job, preview=True, force=True, split="train", protect=protect)
    return RehearsalSummary(frames, len(backdrops), folder / "preview.png")


def _mix(augmented: Path, rehearsal: Path | None, out: Path, valid_frames: int | None) -> SplitCounts:
    """The training set: the augmented export's train frames and every rehearsal frame; the export's valid frames
    (its first ``valid_frames``, the ones the blend is scored on; never its test frames) to validate on. Images are
    linked, not copied."""
    team = load_dataset(augmented)
    rendered = load_dataset(rehearsal).samples if rehearsal is not None else []
    with DatasetWriter(out, force=True, protect=team.input_folders()) as writer:
        for sample in team.split("train") + team.split("valid")[:valid_frames]:
            writer.add(sample.split, sample.image.name, sample.image, sample.instances, link=True)
        for sample in rendered:
            writer.add("train", f"rehearsal_{sample.image.name}", sample.image, sample.instances, link=True)
    return writer.frames


#: A resumed training that had spent its minutes still trains this long: its last epoch ends the schedule.
MIN_RESUMED_MINUTES = 0.1


def _train(key: str, data: Path, run: Path, recipe: FinetuneRecipe, plan: JobPlan,
           spent_minutes: float) -> TrainingSummary:
    """Fine-tune the shipped checkpoint for the minutes left; an interrupted run of the same stage (its key is kept
    beside the run folder) resumes from its last epoch with what is left of its minutes, a finished one is kept. The
    final weights are the fine-tune: a valid split of a few frames cannot choose an epoch. The robot's crop network
    trains in a minute or two and starts again instead."""
    if recipe.start.network == "crops":
        shutil.rmtree(run, ignore_errors=True)
        minutes = training_minutes(plan, spent_minutes)
        console.print(f"training the crop network for at most {recipe.epoch_cap} epochs or {minutes:.1f} minutes")
        return crop_network.train(data, run, recipe.start.weights, recipe.epoch_cap, minutes, recipe.learning_rate,
                                  recipe.seed)

    last, key_file = run / "weights" / "last.pt", run.with_name(f"{run.name}.key")
    same_run = key_file.is_file() and key_file.read_text() == key and last.is_file()
    finished = same_run and read_checkpoint(last).get("epoch", -1) < 0
    if run.exists() and not same_run:
        shutil.rmtree(run)
    key_file.write_text(key)
    done = trained_minutes(run) if same_run else 0.0
    minutes = training_minutes(plan, spent_minutes)
    if same_run:
        minutes = max(minutes - done, MIN_RESUMED_MINUTES)
    cap = f" or {recipe.epoch_cap} epochs, whichever comes first" if recipe.epoch_cap else ""
    resumed = f", resumed after {done:.1f} trained before" if same_run else ""
    console.print(f"training for {minutes:.1f} minutes{cap} ({spent_minutes:.1f} spent preparing, "
                  f"{plan.after_training_seconds() / 60:.1f} kept for what follows{resumed})")
    settings = TrainSettings(model=recipe.start.architecture, epochs=1000, imgsz=recipe.training_size,
                             batch=recipe.batch, patience=1000, seed=recipe.seed, time_hours=minutes / 60,
                             max_epochs=recipe.epoch_cap, hyperparameters=recipe.hyperparameters())
    if not finished:
        train_model(data, run, settings, weights=recipe.start.weights, resume=same_run)
    return summarise_run(run, recipe.start.architecture, recipe.start.weights, round(minutes, 2), kept="last")


def _starting_metadata(recipe: FinetuneRecipe) -> dict:
    """The starting model's ONNX metadata (range calibration, operating threshold), which the fine-tune is judged
    at and ships with."""
    return read_info(resolve_model(recipe.start.shipped)).extra


def judging_predictor(recipe: FinetuneRecipe) -> Callable[[Path], Predictor]:
    """How a checkpoint of the starting model's network is run to be judged."""
    if recipe.start.network == "crops":
        return crop_network.predictor
    return lambda weights: TorchPredictor(weights, recipe.training_size)


def _blend(finetuned: Path, data: Path, folder: Path, conf: float, recipe: FinetuneRecipe,
           frames: int | None) -> BlendChoice:
    if recipe.start.network == "crops":
        blend = crop_network.blend
    else:
        def blend(first: Path, second: Path, share: float, out: Path) -> Path:
            return blend_checkpoints(first, second, share, out, force=True)

    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir(parents=True)
    return choose_blend(recipe.start.weights, finetuned, data, folder, conf, judging_predictor(recipe), blend, frames)


def _export_model(weights: Path, model: Path, data: Path, mixed: Path, recipe: FinetuneRecipe) -> ExportedModel:
    """ONNX of the chosen blend, exported as its starting model is (FP32 and INT8, or FP32 with a dynamic input),
    verified against PyTorch on the export's frames, carrying the starting model's operating threshold and its range
    calibration (where the input width is the one that calibration was measured at; at another width the masks read
    other sizes, and `poles calibrate` must measure them)."""
    start = recipe.start
    if start.network == "crops":
        return crop_network.export(weights, model)
    report = run_export(ExportJob(weights, model, None, data, int8=start.int8, calib_data=mixed if start.int8 else None,
                                  force=True))
    written = [model, int8_path(model)] if start.int8 else [model]
    stamp = _starting_metadata(recipe)
    measured_at = stamp["calibration"].get("input_width")
    calibrated = measured_at == report.width
    if not calibrated:
        stamp = {key: value for key, value in stamp.items() if key != "calibration"}
        console.print(f"[yellow]no range calibration in {model}: the shipped one was measured at "
                      f"{measured_at} px input, this model runs at "
                      f"{report.width} - run `poles calibrate --model {model} --embed {model}`")
    for path in written:
        add_metadata(path, **stamp)
    return ExportedModel(model, int8_path(model) if start.int8 else None, calibrated, check=report)


def _evaluate(folder: Path, data: Path, finetuned: Path, blend: BlendChoice, conf: float,
              recipe: FinetuneRecipe, plan: JobPlan) -> Judgement:
    """Shipped model, fine-tune and chosen blend on the held-out frames (test split, else valid) and on fresh
    rendered sets, at the shipped threshold."""
    shutil.rmtree(folder, ignore_errors=True)
    held_out = "test" if load_dataset(data).split("test") else "valid"
    sets = {f"your {held_out} frames": (data, held_out, plan.held_out_frames)}
    for name, (far_share, seed) in RENDERED_SETS.items():
        sets[name] = (render_set(folder / "sets" / name.replace(" ", "-"), plan.evaluation_frames, far_share, seed),
                      "test", None)
    models = {REFERENCE: recipe.start.weights, "fine-tune": finetuned,
              f"blend {blend.chosen:g}": blend.weights}
    return Judgement(held_out, conf, tuple(compare_models(models, sets, folder, conf, judging_predictor(recipe))))
