"""The commands that run a model on frames: ``evaluate`` scores it on labelled ones, ``predict`` pre-labels new ones
or draws its view on a video, ``pick`` chooses the frames of a recording worth labelling."""
from __future__ import annotations

import argparse
from pathlib import Path

from detector.cli.arguments import add_dataset_argument, add_input_width_argument, confidence, existing
from naoslam.shipped import DEFAULT_CONF


def add_parsers(sub: argparse._SubParsersAction) -> None:
    """Add the `evaluate`, `predict` and `pick` commands to ``sub`` (``run``: the function that runs it)."""
    evaluate = sub.add_parser("evaluate", help="precision, recall and mask IoU per image on held-out frames")
    evaluate.add_argument("--model", action="append",
                          help="a .pt checkpoint (or its `poles train` run folder), an .onnx model, `shipped`, "
                               "`shipped-int8`, `shipped-robot` or `colour-filter`; "
                               "repeat to compare several (default: the shipped model)")
    add_dataset_argument(evaluate, "held-out frames with labels (dataset folder or COCO export)")
    evaluate.add_argument("--split", default="test", help="split to evaluate (default test)")
    evaluate.add_argument("--conf", type=confidence,
                          help="confidence threshold for the counts (default: the model's own, else %g, as predict, slam "
                               "and the robot use it)" % DEFAULT_CONF)
    evaluate.add_argument("--calibration", type=Path, help="calibration.json for range errors "
                                                           "(default: the one embedded in the ONNX model; for the "
                                                           "colour filter, the shipped model's colour law)")
    add_input_width_argument(evaluate, "a .pt checkpoint at 640 unless given; ONNX: ")
    evaluate.add_argument("--pose", action="store_true",
                          help="give ONNX front ends each frame's camera pose where annotations.json records it "
                               "(`poles synth` writes it), as on the robot: the band below the horizon and the "
                               "ground-plane gate")
    evaluate.add_argument("--out", type=Path, required=True, help="folder for metrics.json, plots and FP/FN overlays")
    evaluate.add_argument("--force", action="store_true", help="replace --out if it holds files")
    evaluate.set_defaults(run=_evaluate)

    predict = sub.add_parser("predict", help="pre-label new frames for Roboflow, or draw a model's view on a video")
    source = predict.add_mutually_exclusive_group(required=True)
    source.add_argument("--images", type=Path,
                        help="folder of unlabelled frames (subfolders too): write pre-annotations to --out")
    source.add_argument("--video", type=Path, help="video file or folder of frames in order: write an overlay MP4")
    predict.add_argument("--out", type=Path, required=True, help="dataset folder (--images) or video.mp4 (--video)")
    predict.add_argument("--model", type=Path, help="ONNX model, `shipped-int8` or `shipped-robot` (default: the "
                         "shipped accurate model)")
    predict.add_argument("--conf", type=confidence, help="confidence threshold (default: the model's own)")
    predict.add_argument("--format", choices=("yolov8", "coco"), default="yolov8", help="pre-annotation layout")
    add_input_width_argument(predict, "with --video, to see what a robot running it smaller sees: ")
    predict.add_argument("--force", action="store_true")
    predict.set_defaults(run=_predict)

    pick = sub.add_parser("pick", help="the frames of a recording worth labelling: where the robot front end and the "
                                       "accurate model disagree, pre-labelled for Roboflow")
    pick.add_argument("recording", type=Path, help="folder of frames (subfolders too) or a video")
    pick.add_argument("--count", type=int, default=50, help="frames to pick (default 50)")
    pick.add_argument("--out", type=Path, required=True, help="dataset folder for the picked frames, their "
                      "pre-labels, picked.json and picked.png (why each was picked)")
    pick.add_argument("--teacher", default="shipped", help="the accurate model that pre-labels them: `shipped` or "
                      "an ONNX model, e.g. your fine-tune (default: shipped)")
    pick.add_argument("--robot", default="shipped-robot", help="the robot front end to find the weak spots of: "
                      "`shipped-robot` or a robot ONNX model (default: shipped-robot)")
    pick.add_argument("--format", choices=("yolov8", "coco"), default="yolov8", help="pre-annotation layout")
    pick.add_argument("--force", action="store_true")
    pick.set_defaults(run=_pick)


def _evaluate(args: argparse.Namespace) -> int:
    from detector.datasets.intake import open_dataset
    from detector.evaluation.predictors import make_predictor
    from detector.model_files import load_calibration
    from detector.outputs import output_folder
    from detector.evaluation.run import evaluate, print_metrics

    calibration = load_calibration(args.calibration) if args.calibration else None
    rows = []
    models = args.model or ["shipped"]
    predictors = [make_predictor(model, args.imgsz, calibration) for model in models]  # every model checked first
    for predictor, label in zip(predictors, _column_labels(models, [p.name for p in predictors])):
        predictor.name = label
    dataset = open_dataset(args.data, progress=False)
    if args.pose:
        _say_poses(dataset, args.split)
    inputs = dataset.input_folders() + existing(args.calibration, *map(Path, models))
    with output_folder(args.out, args.force, inputs, "evaluation") as folder:
        for predictor in predictors:
            out = folder / predictor.name if len(models) > 1 else folder
            conf = args.conf if args.conf is not None else predictor.operating_conf or DEFAULT_CONF
            # the dataset was checked (and its warnings said) once, above
            rows.append(evaluate(predictor, args.data, out, args.split, conf, use_pose=args.pose, check=False))
    print_metrics(rows)
    print(f"wrote {args.out} (metrics.json, per_image.png, sweep.png, confusion.png, recall_by_width.png, errors/)")
    return 0


def _say_poses(dataset, split: str) -> None:
    """A note when ``--pose`` finds no camera pose, or not every frame's (naming the first frame whose recorded
    pose no front end can measure on, and why): those frames are searched whole."""
    from detector.datasets.truth import camera_pose_problems, load_camera_poses

    frames = {sample.image.name for sample in dataset.split(split)}
    problems = {name: problem for name, problem in sorted(camera_pose_problems(dataset).items()) if name in frames}
    posed = len(frames & set(load_camera_poses(dataset))) + len(problems)
    if posed < len(frames):
        which = "none" if not posed else f"{posed} of {len(frames)}"
        print(f"note: --pose: {which} of the {split} frames record their camera pose (annotations.json, as `poles "
              "synth` writes it); the others are searched whole, as without --pose")
    if problems:
        name, problem = next(iter(problems.items()))
        print(f"note: --pose: {len(problems)} of the {split} frames record a pose no front end can measure on and "
              f"are searched whole ({name}: {problem}) - correct their camera entries in annotations.json")


def _column_labels(models: list[str], names: list[str]) -> list[str]:
    """Each evaluated model's table column and folder: its file name, or, where two share one, ``FOLDER_NAME``
    (``runs/a/best.onnx`` -> ``a_best.onnx``), numbered where that is shared too; two models never share a folder."""
    labels = [name if names.count(name) == 1 or not Path(model).parent.name else f"{Path(model).parent.name}_{name}"
              for model, name in zip(models, names)]
    return [label if labels[:index].count(label) == 0 else f"{label}-{labels[:index].count(label) + 1}"
            for index, label in enumerate(labels)]


def _predict(args: argparse.Namespace) -> int:
    from detector.prediction import overlay_video, prelabel

    if args.images is not None:
        if args.imgsz is not None:
            raise ValueError("--imgsz is for --video: pre-labels come from the model at its own input size")
        result = prelabel(args.images, args.out, args.model, args.conf, args.format, args.force)
        print(f"pre-labelled {result.frames} frames ({result.poles} poles, {result.empty} without) at conf "
              f"{result.conf:.2f}: {result.out} - upload it to Roboflow as pre-annotations, correct, export")
    else:
        video = overlay_video(args.video, args.out, args.model, args.conf, args.force, input_width=args.imgsz)
        print(f"wrote {video.frames} frames to {video.video} and the contact sheet {video.sheet}"
              + ("" if video.ranges else " (no ranges drawn: the model has no calibration for this input width)"))
    return 0


def _pick(args: argparse.Namespace) -> int:
    from detector.picking import pick_frames

    result = pick_frames(args.recording, args.out, args.count, args.teacher, args.robot, args.format, args.force)
    print(f"compared {result.frames} frames: the robot front end (threshold {result.robot_conf:.2f}) and the "
          f"accurate model ({result.accurate_conf:.2f}) disagree on {result.disagreeing}; picked {len(result.picked)} "
          f"spread over the recording into {result.out} with the accurate model's pre-labels - upload it to Roboflow, "
          f"correct, export; why each was picked: {result.sheet}")
    return 0
