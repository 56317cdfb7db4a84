"""The dataset commands: ``synth`` renders one, ``check`` validates it, ``convert`` rewrites it, ``augment`` and
``split`` derive new ones from it."""
from __future__ import annotations

import argparse
from pathlib import Path

from augment.config import OPERATIONS, THESIS_COPIES, AugmentConfig
from detector.formats import write_record
from detector.cli.arguments import add_dataset_argument, existing, finite_number, image_size, whole_number
from detector.datasets.split import THESIS_RATIOS
from detector.synth.scene import SceneConfig
from naoslam.camera import NAO_HFOV_DEG
from naoslam.sim import PATHS


#: Augmentation strength limits that have a flag of their own (AugmentConfig field -> help text).
STRENGTH_FLAGS = {"rotate_deg": "whole-image rotation limit", "shear_deg": "shear limit",
                  "saturation": "saturation change limit (fraction)",
                  "brightness": "brightness change limit (fraction)",
                  "box_rotate_deg": "box rotation limit", "box_brightness": "box brightness change limit (fraction)",
                  "box_blur_px": "box blur sigma limit (px)"}


def add_parsers(sub: argparse._SubParsersAction) -> None:
    """Add the `synth`, `check`, `convert`, `augment` and `split` commands to ``sub`` (``run``: the function that
    runs it)."""
    synth = sub.add_parser("synth", help="render a synthetic annotated pole dataset (Roboflow YOLOv8 layout)")
    synth.add_argument("--out", type=Path, required=True, help="output dataset folder (must not exist, or use --force)")
    synth.add_argument("--images", type=int, help="number of images (default 500; with --walk, all its frames)")
    synth.add_argument("--seed", type=whole_number(0), default=0, help="random seed: same seed, same dataset")
    synth.add_argument("--size", type=image_size, default=(640, 480), help="image size WIDTHxHEIGHT (default 640x480)")
    synth.add_argument("--hfov", type=finite_number, default=NAO_HFOV_DEG,
                       help=f"horizontal field of view in degrees (default {NAO_HFOV_DEG}, the Nao's top camera)")
    synth.add_argument("--calibration-shots", action="store_true",
                       help="one pole per image at known distances 0.5-5 m and angles 0, +-10, +-20 deg")
    synth.add_argument("--walk", choices=PATHS,
                       help="the frames of the walk `poles slam --sim WALK --seed SEED` sees, labelled with true "
                            "ranges: a walking robot's sightings for `poles calibrate --noise-data`")
    synth.add_argument("--backgrounds", type=Path,
                       help="folder of real robot-camera frames without poles: draw the poles over them")
    synth.add_argument("--backdrop-share", type=finite_number, default=1.0,
                       help="with --backgrounds, the fraction of frames drawn over them (default 1; the rest ray-cast)")
    synth.add_argument("--nominal-paint-share", type=finite_number,
                       help="share of frames whose poles keep the nominal paint; the rest vary hue, saturation and "
                            f"value per band (default {SceneConfig.nominal_paint_share})")
    synth.add_argument("--far-share", type=finite_number,
                       help="share of frames whose poles all stand %g-%g m away, 6-18 px wide at 640x480 "
                            "(default 0: 0.4-9 m, log-uniform)" % SceneConfig.far_range_m)
    synth.add_argument("--backlight-share", type=finite_number,
                       help="with --backgrounds, the share of backdrop frames whose poles stand back-lit, dark and "
                            f"hazed as in front of a window (default {SceneConfig.backlight_share})")
    synth.add_argument("--paint-from", type=Path, metavar="EXPORT",
                       help="paint every pole with the band colours measured on this annotated export's train and "
                            "valid frames (your own poles, in your own light); written to paint.json beside the frames")
    synth.add_argument("--preview", action="store_true",
                       help="also write preview.png, a contact sheet with labels drawn")
    synth.add_argument("--workers", type=whole_number(0), default=None, help="render processes (default: every core)")
    synth.add_argument("--force", action="store_true", help="replace --out if it exists")
    synth.set_defaults(run=_synth)

    check = sub.add_parser("check", help="validate a dataset and print a summary and every problem")
    add_dataset_argument(check, "dataset folder (with data.yaml) or Roboflow COCO export folder")
    check.add_argument("--fix", action="store_true", help="write a cleaned copy to --out (never in place)")
    check.add_argument("--out", type=Path, help="where --fix writes the cleaned copy")
    check.add_argument("--notes", action="store_true", help="also list notes (e.g. images without a label file)")
    check.add_argument("--force", action="store_true", help="replace --out if it exists")
    check.set_defaults(run=_check)

    convert = sub.add_parser("convert",
                             help="write any readable dataset (e.g. a COCO export) in the Roboflow YOLOv8 layout")
    add_dataset_argument(convert, "dataset folder (with data.yaml) or Roboflow COCO export folder")
    convert.add_argument("--out", type=Path, required=True)
    convert.add_argument("--rename", action="append", metavar="OLD=NEW",
                         help="read the export's class OLD as landmark NEW (e.g. pink-blue=pb); repeat for each")
    convert.add_argument("--force", action="store_true")
    convert.set_defaults(run=_convert)

    augment = sub.add_parser("augment", help="add N augmented copies of every training image (labels kept exact)")
    add_dataset_argument(augment, "input dataset (never written)")
    augment.add_argument("--out", type=Path, required=True, help="output dataset folder")
    augment.add_argument("--copies", type=int, default=THESIS_COPIES,
                         help=f"copies per training image (default, as the thesis: {THESIS_COPIES})")
    augment.add_argument("--seed", type=whole_number(0), default=0)
    augment.add_argument("--ops", help=f"comma-separated operations to draw from (default all: {','.join(OPERATIONS)})")
    augment.add_argument("--config", type=Path,
                         help="YAML with strength limits, e.g. `rotate_deg: 15`, `box_blur_px: 1.5`")
    defaults = AugmentConfig()
    for name, text in STRENGTH_FLAGS.items():
        augment.add_argument(f"--{name.replace('_', '-')}", type=finite_number, default=None,
                             help=f"{text} (default {getattr(defaults, name)})")
    augment.add_argument("--preview", action="store_true", help="write augment_preview.png: originals beside copies")
    augment.add_argument("--workers", type=whole_number(0), default=None)
    augment.add_argument("--force", action="store_true")
    augment.set_defaults(run=_augment)

    split = sub.add_parser("split", help="re-split a dataset, stratified so every class reaches every split")
    add_dataset_argument(split, "dataset folder to re-split (never written)")
    split.add_argument("--out", type=Path, required=True)
    split.add_argument("--ratios", type=finite_number, nargs=3, default=THESIS_RATIOS,
                       metavar=("TRAIN", "TEST", "VALID"),
                       help="fractions for train, test and valid (default, as the thesis: "
                            f"{' '.join(f'{r:g}' for r in THESIS_RATIOS)})")
    split.add_argument("--seed", type=whole_number(0), default=0)
    split.add_argument("--force", action="store_true")
    split.set_defaults(run=_split)


def _synth(args: argparse.Namespace) -> int:
    from detector.synth.backdrops import scan_backdrops
    from detector.synth.generate import DEFAULT_SYNTH_IMAGES, SynthJob, generate_dataset
    from detector.synth.walk import walk_frame_steps

    images = args.images if args.images is not None else (
        len(walk_frame_steps(args.walk, args.seed)) if args.walk else DEFAULT_SYNTH_IMAGES)
    if images < 1:
        raise ValueError("--images must be at least 1")
    options = {name: value for name, value in (("nominal_paint_share", args.nominal_paint_share),
                                               ("far_share", args.far_share),
                                               ("backlight_share", args.backlight_share)) if value is not None}
    flags = " and ".join("--" + name.replace("_", "-") for name in options)
    if args.walk and options:
        raise ValueError(f"--walk places and paints its poles as `poles slam` renders them: leave out {flags}")
    if args.calibration_shots and options:
        raise ValueError("--calibration-shots stands one nominally painted pole at each set distance: "
                         f"leave out {flags}")
    if args.backlight_share is not None and args.backgrounds is None:
        raise ValueError("--backlight-share lights the poles drawn over real frames: give --backgrounds too")
    if args.paint_from is not None and (args.walk or args.calibration_shots or args.nominal_paint_share is not None):
        raise ValueError("--paint-from paints the random scenes' poles: leave out --walk, --calibration-shots and "
                         "--nominal-paint-share")
    paint = _team_paint(args.paint_from) if args.paint_from is not None else None
    config = SceneConfig(**options, team_paint=paint.scene_paint() if paint else ())
    backgrounds = scan_backdrops(args.backgrounds) if args.backgrounds is not None else ()
    job = SynthJob(images, args.seed, *args.size, hfov_deg=args.hfov, calibration_shots=args.calibration_shots,
                   backgrounds=backgrounds, backdrop_share=args.backdrop_share, walk=args.walk, config=config)
    out = generate_dataset(args.out, job, workers=args.workers, preview=args.preview, force=args.force,
                           protect=existing(args.backgrounds, args.paint_from))
    if paint is not None:
        write_record(out / "paint.json", "paint", paint.to_json())
    print(f"wrote {images} images to {out}")
    return 0


def _team_paint(export: Path):
    """Measure and print the paint of ``export``'s poles (``team_paint.TeamPaint``)."""
    from detector.synth.team_paint import measure_team_paint

    paint = measure_team_paint(export)
    hues = ", ".join(f"{letter} {paint.hue_degrees(letter):.0f} deg ({count} bands)"
                     for letter, count in paint.measured.items() if count)
    print(f"paint from {export}: {paint.poles} poles measured, {paint.skipped} too small; hue {hues}")
    missing = [letter for letter, count in paint.measured.items() if not count]
    if missing:
        print(f"note: no pole of the export shows band colour {', '.join(missing)}: the nominal paint is used for it")
    return paint


def _check(args: argparse.Namespace) -> int:
    from detector.datasets.check import check_dataset, listing_path, print_report, write_fixed_copy
    from detector.datasets.io import DATASET
    from detector.outputs import check_output_folder

    if args.fix and args.out is None:
        raise ValueError("--fix needs --out CLEAN: the cleaned copy is never written in place")
    report = check_dataset(args.data)
    if args.fix:  # refused before the list of problems is written beside it
        check_output_folder(args.out, args.force, report.dataset.input_folders(), DATASET)
    print_report(report, show_notes=args.notes, full_list=listing_path(report.dataset, args.out if args.fix else None))
    if args.fix:
        print(f"cleaned copy: {write_fixed_copy(report, args.out, force=args.force)}")
    return 1 if report.errors else 0


def _convert(args: argparse.Namespace) -> int:
    from detector.datasets import write_dataset
    from detector.datasets.intake import open_dataset
    from detector.datasets.names import parse_renames

    dataset = open_dataset(args.data, parse_renames(args.rename))
    print(f"wrote {write_dataset(args.out, dataset, force=args.force)}")
    return 0


def _augment(args: argparse.Namespace) -> int:
    from augment.run import augment_dataset

    settings = {name: getattr(args, name) for name in STRENGTH_FLAGS}
    if args.ops:
        settings["ops"] = tuple(op.strip() for op in args.ops.split(",") if op.strip())
    config = (AugmentConfig.from_yaml(args.config, **settings) if args.config
              else AugmentConfig(**{k: v for k, v in settings.items() if v is not None}))
    summary = augment_dataset(args.data, args.out, copies=args.copies, seed=args.seed, config=config,
                              preview=args.preview, force=args.force, workers=args.workers)
    print(f"train images: {summary.train_images_in} -> {summary.train_images_out}; instances in copies kept "
          f"{summary.instances_kept}, dropped {summary.instances_dropped} (clipped away or too small)")
    print("operations used: " + (", ".join(f"{k} {v}" for k, v in sorted(summary.operations.items())) or "none"))
    if summary.preview is not None:
        print(f"preview: {summary.preview}")
    return 0


def _split(args: argparse.Namespace) -> int:
    from detector.datasets.split import RATIO_ORDER, split_dataset

    counts = split_dataset(args.data, args.out, tuple(args.ratios), seed=args.seed, force=args.force)
    total = sum(args.ratios)
    if abs(total - 1) > 1e-6:  # the split divides by the sum; say so rather than let 0.7 0.2 0.2 pass unnoticed
        shares = ", ".join(f"{split} {100 * r / total:.0f} %" for split, r in zip(RATIO_ORDER, args.ratios))
        print(f"--ratios sum to {total:g}, so they were used as shares: {shares}")
    print(f"images per split: train {counts.train}, valid {counts.valid}, test {counts.test}")
    return 0
