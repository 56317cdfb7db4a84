"""The model commands: ``train`` one, ``export`` it to ONNX, ``soup`` two checkpoints into one, ``calibrate`` its
ranges."""
from __future__ import annotations

import argparse
from pathlib import Path

from detector.cli.arguments import (add_dataset_argument, add_input_width_argument, confidence, finite_number,
                                    thread_choice, whole_number)
from detector.training import defaults
from detector.training.openmp_wait import choose_wait_policy
from detector.model_files import run_checkpoint
from naoslam.shipped import DEFAULT_CONF


def add_parsers(sub: argparse._SubParsersAction) -> None:
    """Add the `train`, `export`, `soup` and `calibrate` commands to ``sub`` (``run``: the function that runs it)."""
    train = sub.add_parser("train", help="train a YOLOv8 segmentation model on the CPU (offline, every core)")
    add_dataset_argument(train, "dataset folder with data.yaml")
    train.add_argument("--out", type=Path, required=True, help="run folder (weights/best.pt, results.csv, curves)")
    train.add_argument("--model", help=f"{defaults.MODEL} (default), yolov8s-seg, yolov8m-seg, or robot-p4-seg / "
                       "robot-p5-seg (small enough for the Nao's CPU; train them at --imgsz 320)")
    train.add_argument("--weights", help="checkpoint (or `poles train` run folder) to fine-tune from (default: the "
                                         "shipped pole model for yolov8n-seg), or `scratch` to train from the "
                                         "architecture alone")
    train.add_argument("--teacher", type=run_checkpoint,
                       help="distil from this larger model (a checkpoint or `poles train` run folder, e.g. "
                            "detector/weights/poles-yolov8n-seg.pt): the network also learns its features at the "
                            "strides both have")
    train.add_argument("--epochs", type=whole_number(1), default=defaults.EPOCHS,
                       help=f"epochs to train (default {defaults.EPOCHS}; --time overrides)")
    train.add_argument("--time", type=finite_number,
                       help="train for this many hours instead (Ultralytics fits the epochs)")
    train.add_argument("--imgsz", type=whole_number(32), default=defaults.IMGSZ,
                       help=f"training image size (default {defaults.IMGSZ})")
    train.add_argument("--batch", type=whole_number(1), default=defaults.BATCH,
                       help=f"images per batch (default {defaults.BATCH})")
    train.add_argument("--patience", type=whole_number(0), default=defaults.PATIENCE,
                       help=f"stop after this many epochs without improvement (default {defaults.PATIENCE}; 0: never "
                            "stop early)")
    train.add_argument("--seed", type=whole_number(0), default=defaults.SEED,
                       help=f"random seed (default {defaults.SEED})")
    train.add_argument("--threads", type=thread_choice,
                       help="torch threads: `shared` (default): every core, waiting threads sleep, so other programs "
                            "on the machine do not slow training down many times over; `all`: every core, waiting "
                            "threads spin (about 10 %% faster on an idle machine); a number; `auto` to re-time the "
                            "count while training")
    train.add_argument("--workers", type=whole_number(0), default=defaults.WORKERS,
                       help=f"data-loader processes (default {defaults.WORKERS}: best on 2 cores)")
    train.add_argument("--no-cache", action="store_true", help="do not cache decoded images in RAM")
    train.add_argument("--device", default=defaults.DEVICE,
                       help="cpu (default), a GPU index such as 0, several such as 0,1 (Ultralytics' DDP), or mps")
    train.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", dest="hyperparameters",
                       help="any other Ultralytics training argument, e.g. --set lr0=0.0002 --set mosaic=0; repeat "
                            "for each (checked by Ultralytics; the flags above cannot be set this way)")
    train.add_argument("--resume", action="store_true", help="continue the interrupted run in --out")
    train.set_defaults(run=_train)

    export = sub.add_parser("export", help="export to ONNX (FP32, optional INT8), verified against PyTorch")
    export.add_argument("--weights", type=run_checkpoint, required=True,
                        help="trained checkpoint (best.pt), or the `poles train` run folder that holds it")
    export.add_argument("--out", type=Path, required=True,
                        help="ONNX file to write, e.g. model.onnx (INT8 goes beside it as *-int8.onnx)")
    export.add_argument("--imgsz", type=int, nargs=2, metavar=("HEIGHT", "WIDTH"),
                        help="network input (default: the width the model was trained at, the height in the "
                             "proportion of the --data frames: 480 640 for the Nao's frames at 640 px)")
    export.add_argument("--data", type=Path, help="dataset whose valid/test frames verify the export "
                                                  "(default: the one the model was trained on)")
    export.add_argument("--int8", action="store_true", help="also write a static INT8 copy")
    export.add_argument("--calib-data", type=Path, help="dataset whose training images calibrate INT8 (default --data)")
    export.add_argument("--reduce-range", action="store_true", help="7-bit INT8 weights, for x86 CPUs without VNNI")
    export.add_argument("--conf", type=confidence, default=DEFAULT_CONF,
                        help=f"confidence threshold used when verifying (default {DEFAULT_CONF})")
    export.add_argument("--dynamic", action="store_true",
                        help="any input size (multiples of 32), so the front end can run on the band below the "
                             "horizon alone when it knows the camera pose")
    export.add_argument("--force", action="store_true", help="replace existing output files")
    export.set_defaults(run=_export)

    soup = sub.add_parser("soup", help="blend two checkpoints of one network: (1 - alpha) * first + alpha * second")
    soup.add_argument("--weights", type=run_checkpoint, nargs=2, required=True, metavar=("FIRST", "SECOND"),
                      help="two checkpoints of one architecture (or `poles train` run folders), e.g. the shipped "
                           "model's and your fine-tune of it")
    soup.add_argument("--alpha", type=finite_number, required=True, help="the second checkpoint's share, 0-1")
    soup.add_argument("--out", type=Path, required=True, help="checkpoint to write (export it with `poles export`)")
    soup.add_argument("--force", action="store_true", help="replace an existing --out")
    soup.set_defaults(run=_soup)

    calib = sub.add_parser("calibrate", help="fit range = a * px^b from poles of known distance")
    add_dataset_argument(calib, "dataset whose annotations.json (or --truth CSV) gives each pole's true range")
    calib.add_argument("--out", type=Path, required=True, help="calibration.json to write")
    source = calib.add_mutually_exclusive_group()
    source.add_argument("--model", type=Path, help="measure the masks this ONNX model finds")
    source.add_argument("--from-labels", action="store_true", help="measure the labelled masks (default)")
    calib.add_argument("--truth", type=Path, help="CSV image,class,range_m instead of annotations.json")
    calib.add_argument("--plot", type=Path, help="write the fit plot (PNG)")
    calib.add_argument("--embed", type=Path, action="append", default=[], metavar="MODEL",
                       help="store the calibration in this ONNX model's metadata; repeat for each model that will "
                            "use it, e.g. the FP32 model and its INT8 copy")
    add_input_width_argument(calib, "measure --model's masks as the robot will run it: ")
    calib.add_argument("--noise-data", type=Path, action="append", default=[], metavar="WALK",
                       help="frames of a walk with true ranges (`poles synth --walk`, or your own robot's with "
                            "annotations.json), measured like --data: the noise the filter is told (repeatable; "
                            "default: the walk floor measured with the shipped model)")
    calib.add_argument("--force", action="store_true")
    calib.set_defaults(run=_calibrate)


def _train(args: argparse.Namespace) -> int:
    choose_wait_policy(args.threads)
    from detector.training.starting_point import starting_point
    from detector.training.train import TrainSettings, parse_hyperparameters, summarise_run, train_model

    if args.resume and args.hyperparameters:
        raise ValueError("--set with --resume: a resumed run keeps the arguments it started with - drop --set")
    model, weights = (args.model or "", None) if args.resume else starting_point(args.model, args.weights)
    threads = args.threads if isinstance(args.threads, int) else None
    settings = TrainSettings(model=model or defaults.MODEL, epochs=args.epochs, imgsz=args.imgsz, batch=args.batch,
                             patience=args.patience, seed=args.seed, threads=threads,
                             adaptive_threads=args.threads == "auto", workers=args.workers,
                             cache=not args.no_cache, time_hours=args.time, device=args.device, teacher=args.teacher,
                             hyperparameters=parse_hyperparameters(args.hyperparameters))
    run = train_model(args.data, args.out, settings, weights=weights, resume=args.resume)
    summary = summarise_run(run, settings.model, weights, 60 * args.time if args.time else None)
    best = summary.best
    print(f"best epoch {best.epoch} of {best.epochs} (validation): mask mAP50 {best.mask_map50:.3f}, "
          f"mAP50-95 {best.mask_map50_95:.3f}; weights {summary.weights}; curves {summary.curves}")
    return 0


def _export(args: argparse.Namespace) -> int:
    from export.run import ExportJob, print_report, run_export

    job = ExportJob(args.weights, args.out, tuple(args.imgsz) if args.imgsz else None, args.data, args.int8, args.calib_data,
                    args.reduce_range, args.conf, args.force, args.dynamic)
    print_report(run_export(job))
    return 0


def _soup(args: argparse.Namespace) -> int:
    from detector.training.soup import blend_checkpoints

    first, second = args.weights
    out = blend_checkpoints(first, second, args.alpha, args.out, args.force)
    print(f"wrote {out}: (1 - {args.alpha:g}) * {first} + {args.alpha:g} * {second}")
    return 0


def _calibrate(args: argparse.Namespace) -> int:
    from calibration.run import print_calibration, run_calibration
    from export.onnx_export import int8_path

    result = run_calibration(args.data, args.out, args.model, args.truth, args.plot, args.embed, args.force,
                             args.noise_data, args.imgsz)
    print_calibration(result)
    embedded = ", ".join(map(str, args.embed))
    print(f"wrote {args.out}" + (f", {args.plot}" if args.plot else "")
          + (f"; embedded in {embedded}" if embedded else ""))
    for int8 in map(int8_path, args.embed):
        if int8.is_file() and int8 not in args.embed:
            print(f"note: {int8}, its INT8 copy, was not given this calibration: add --embed {int8} to range with it")
    return 0
