"""``poles finetune``: a team's own annotated export to a deployable model, with what it gained and lost."""
from __future__ import annotations

import argparse
from pathlib import Path

from detector.cli.arguments import finite_number, minutes_number, positive_number, whole_number
from detector.finetune.recipe import STARTING_MODELS, FinetuneRecipe

DEFAULTS = FinetuneRecipe()
ACCURATE, ROBOT = STARTING_MODELS["accurate"], STARTING_MODELS["robot"]


def add_parsers(sub: argparse._SubParsersAction) -> None:
    """Add the `finetune` command to ``sub`` (``run``: the function that runs it)."""
    finetune = sub.add_parser("finetune", help="fine-tune the shipped model on your own annotated export, "
                                               "blend, export, and report what changed (resumable)")
    finetune.add_argument("export", type=Path, nargs="?",
                          help="your annotated export: Roboflow YOLOv8 or COCO folder (only read); may be left out "
                               "with --unlabelled")
    finetune.add_argument("--out", type=Path, required=True,
                          help="run folder: models/poles-finetuned.onnx (+ -int8), report.html, metrics.json; "
                               "give an earlier run's folder to resume it")
    finetune.add_argument("--model", choices=STARTING_MODELS, default=DEFAULTS.model,
                          help="the shipped model to start from: accurate (default; FP32 + INT8 out) or robot (the "
                               "two-stage front end for the Nao: its crop network; FP32 out)")
    finetune.add_argument("--minutes", type=minutes_number, default=DEFAULTS.minutes,
                          help=f"the whole job's time on this machine (default {DEFAULTS.minutes:g}); training "
                               "gets what preparing and evaluating leave")
    finetune.add_argument("--epochs", type=whole_number(1),
                          help="at most this many training epochs within the minutes (default: "
                               f"{ACCURATE.epochs or 'as many as the minutes allow'} for the accurate model, "
                               f"{ROBOT.epochs} for the robot one)")
    finetune.add_argument("--rename", action="append", metavar="OLD=NEW",
                          help="read the export's class OLD as landmark NEW (e.g. pink-blue=pb); repeat for each")
    finetune.add_argument("--rehearsal-share", type=finite_number,
                          help="share of the training frames rendered in your paint: far poles, frames without "
                               f"poles, look-alikes your export may not show (default {ACCURATE.rehearsal_share:g} for "
                               f"the accurate model, {ROBOT.rehearsal_share:g} for the robot one; 0: your frames alone)")
    finetune.add_argument("--backgrounds", type=Path,
                          help="frames of your own field without poles, from the robot's camera: "
                               f"{100 * DEFAULTS.backdrop_share:.0f} %% of the rendered frames are drawn over them, so the "
                               "fine-tune keeps seeing real clutter without poles (default: rendered rooms only)")
    finetune.add_argument("--freeze", type=whole_number(0), default=DEFAULTS.freeze,
                          help="the accurate model's first layers kept as shipped (default: its backbone, "
                               f"{ACCURATE.backbone_layers} layers; 0: none)")
    finetune.add_argument("--lr0", type=positive_number, default=DEFAULTS.lr0,
                          help=f"AdamW learning rate (default {ACCURATE.lr0:g} for the accurate model, "
                               f"{ROBOT.lr0:g} for the robot one)")
    finetune.add_argument("--copies", type=whole_number(0), default=DEFAULTS.copies,
                          help=f"augmented copies of each of your training frames (default {DEFAULTS.copies}, "
                               "the thesis's)")
    finetune.add_argument("--imgsz", type=whole_number(32), default=DEFAULTS.imgsz,
                          help=f"the accurate model's training image size (default {ACCURATE.imgsz})")
    finetune.add_argument("--evaluation-frames", type=whole_number(10), default=DEFAULTS.evaluation_frames,
                          help="frames in each rendered set the models are judged on (default "
                               f"{DEFAULTS.evaluation_frames})")
    finetune.add_argument("--unlabelled", type=Path,
                          help="with --model robot: a folder of your unlabelled frames (or a video) that the accurate "
                               "model labels where it is sure; the robot model trains on them beside the export")
    finetune.add_argument("--teacher", default=DEFAULTS.teacher,
                          help="with --unlabelled, the accurate model that labels them: `shipped` (default, sure at "
                               "its 95 %% precision threshold) or your fine-tune's ONNX (sure at its own threshold)")
    finetune.add_argument("--seed", type=whole_number(0), default=DEFAULTS.seed)
    finetune.set_defaults(run=_finetune)


def _finetune(args: argparse.Namespace) -> int:
    from detector.datasets.names import parse_renames
    from detector.finetune.pipeline import run_finetune
    from detector.finetune.report import changes

    recipe = FinetuneRecipe(model=args.model, minutes=args.minutes, epochs=args.epochs, copies=args.copies,
                            rehearsal_share=args.rehearsal_share,
                            backgrounds=str(args.backgrounds) if args.backgrounds else None, freeze=args.freeze,
                            lr0=args.lr0, imgsz=args.imgsz, seed=args.seed,
                            evaluation_frames=args.evaluation_frames,
                            unlabelled=str(args.unlabelled) if args.unlabelled else None, teacher=args.teacher)
    result = run_finetune(args.export, args.out, recipe, parse_renames(args.rename))
    stages = result.stages
    for line in changes(stages.evaluate):
        print(line)
    int8 = f" (INT8: {stages.export.int8})" if stages.export.int8 else ""
    print(f"blend share {stages.blend.chosen:g} chosen on your valid split; model: {stages.export.fp32}{int8}; "
          f"report: {result.report}")
    return 0
