"""The ``poles`` command line: one subcommand per pipeline stage."""
from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable
from pathlib import Path

from augment.config import OPERATIONS, AugmentConfig
from detector.errors import run_command
from detector.training.openmp_wait import sleep_while_waiting
from detector.training.starting_point import run_checkpoint
from detector.synth.scene import SceneConfig
from naoslam.sim import PATHS, SimConfig


#: Augmentation strength limits that have a flag of their own (AugmentConfig field -> help text).
STRENGTH_FLAGS = {"rotate_deg": "whole-image rotation limit", "shear_deg": "shear limit",
                  "saturation": "saturation change limit (fraction)", "brightness": "brightness change limit (fraction)",
                  "box_rotate_deg": "box rotation limit", "box_brightness": "box brightness change limit (fraction)",
                  "box_blur_px": "box blur sigma limit (px)"}

#: ``poles evaluate``'s threshold for a model that stores none.
FALLBACK_CONF = 0.5


def _size(text: str) -> tuple[int, int]:
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"size {text!r} is not WIDTHxHEIGHT, e.g. 640x480") from None
    if width < 32 or height < 32:
        raise argparse.ArgumentTypeError(f"size {text!r} is too small (at least 32x32)")
    return width, height


def _confidence(text: str) -> float:
    """A ``--conf`` value: a number between 0 and 1 (``naoslam.detector.valid_confidence``)."""
    from naoslam.detector import valid_confidence

    try:
        return valid_confidence(float(text))
    except ValueError as error:
        raise argparse.ArgumentTypeError(f"{text!r}: {error}") from None


def _number(text: str) -> float:
    """An argparse type for a real number: ``float`` also takes ``nan`` and ``inf``, which no setting means."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite number")
    return value


def _positive_number(text: str) -> float:
    """An argparse type for a finite number above 0 (a duration, a scale)."""
    value = _number(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"{text!r}: give a number above 0")
    return value


def _whole_number(minimum: int) -> Callable[[str], int]:
    """An argparse type for a count or a seed: a whole number, ``minimum`` or more."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"{value}: give {minimum} or more")
        return value

    return parse


def _numbers(names: str, positive: bool = False) -> Callable[[str], tuple[float, ...]]:
    """An argparse type for comma-separated finite numbers (above 0 if ``positive``), one per name in ``names``
    (e.g. ``"X,Y,THETA"``)."""
    count = len(names.split(","))

    def parse(text: str) -> tuple[float, ...]:
        try:
            values = tuple(_number(v) for v in text.split(","))
        except argparse.ArgumentTypeError:
            values = ()
        if len(values) != count or (positive and min(values) <= 0):
            kind = "positive numbers" if positive else "numbers"
            raise argparse.ArgumentTypeError(f"{text!r}: give {names} as {count} {kind} separated by commas")
        return values

    return parse


def _threads(text: str) -> int | str:
    if text in ("auto", "shared", "all"):
        return text
    try:
        return _whole_number(1)(text)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(f"--threads {text!r}: give a number of threads (1 or more), `shared`, `all` "
                                         "or `auto`") from None


def _add_dataset_argument(parser: argparse.ArgumentParser, description: str) -> None:
    """The dataset as a first positional DATA or, as every other command takes it, as ``--data DATA``."""
    parser.add_argument("data", type=Path, nargs="?", help=description)
    parser.add_argument("--data", dest="data_option", type=Path, metavar="DATA", help="the same as DATA")


def _add_input_width_argument(parser: argparse.ArgumentParser, applies: str = "") -> None:
    """``--imgsz W``: run the ONNX model at W px wide (``LandmarkDetector(input_width=W)``), as a slower CPU would."""
    parser.add_argument("--imgsz", type=int, help=f"{applies}the model's input width, e.g. 320 for a slower CPU (a "
                                                  "model exported with --dynamic; default: its own)")


def _existing(*paths: Path | None) -> tuple[Path, ...]:
    """The given paths that exist: the inputs an output folder must never overlap (`shipped` and the like are not
    paths)."""
    return tuple(path for path in paths if path is not None and path.exists())


def _one_dataset(args: argparse.Namespace) -> Path:
    """The dataset given as DATA or ``--data``, whichever was given (refused when neither or two differ)."""
    given = {path for path in (args.data, args.data_option) if path is not None}
    if len(given) != 1:
        raise ValueError("give the dataset once, as DATA or as --data DATA")
    return given.pop()


def version_text() -> str:
    """What ``poles --version`` prints, for a bug report: this package, the shipped model it runs by default
    (file hash, threshold) and the versions of the libraries that train and run it."""
    import hashlib
    from importlib.metadata import PackageNotFoundError, version

    from naoslam.shipped import shipped_path

    def installed(name: str) -> str:
        try:
            return version(name)
        except PackageNotFoundError:
            return "not installed"

    model = shipped_path()
    if model.is_file():
        from naoslam.detector import LandmarkDetector

        digest = hashlib.sha256(model.read_bytes()).hexdigest()[:12]
        shipped = f"{model.name} (sha256 {digest}, threshold {LandmarkDetector(model).stored_conf})"
    else:
        shipped = "missing from this installation"
    libraries = ", ".join(f"{name} {installed(name)}" for name in
                          ("onnxruntime", "opencv-python-headless", "ultralytics-opencv-headless", "torch"))
    return f"poles {installed('nao-poles')}\nshipped model: {shipped}\n{libraries}"


class _PrintVersion(argparse.Action):
    """``--version``, worked out only when asked for (it opens the shipped model)."""

    def __init__(self, option_strings: list[str], dest: str, **kwargs) -> None:
        super().__init__(option_strings, dest, nargs=0, help="print the version, the shipped model and the libraries")

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        print(version_text())
        parser.exit()


def build_parser() -> argparse.ArgumentParser:
    """The ``poles`` parser: one subparser per pipeline stage, each flag with its default in its help."""
    parser = argparse.ArgumentParser(prog="poles", description="Coloured-pole landmark detector pipeline for the Nao.")
    parser.add_argument("--version", action=_PrintVersion)
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    synth = sub.add_parser("synth", help="render a synthetic annotated pole dataset (Roboflow YOLOv8 layout)")
    synth.add_argument("--out", type=Path, required=True, help="output dataset folder (must not exist, or use --force)")
    synth.add_argument("--images", type=int, help="number of images (default 500; with --walk, all its frames)")
    synth.add_argument("--seed", type=_whole_number(0), default=0, help="random seed: same seed, same dataset")
    synth.add_argument("--size", type=_size, default=(640, 480), help="image size WIDTHxHEIGHT (default 640x480)")
    synth.add_argument("--hfov", type=_number, default=56.3, help="horizontal field of view in degrees (default 56.3)")
    synth.add_argument("--calibration-shots", action="store_true",
                       help="one pole per image at known distances 0.5-5 m and angles 0, +-10, +-20 deg")
    synth.add_argument("--walk", choices=PATHS,
                       help="the frames of the walk `poles slam --sim WALK --seed SEED` sees, labelled with true "
                            "ranges: a walking robot's sightings for `poles calibrate --noise-data`")
    synth.add_argument("--backgrounds", type=Path,
                       help="folder of real robot-camera frames without poles: draw the poles over them")
    synth.add_argument("--backdrop-share", type=_number, default=1.0,
                       help="with --backgrounds, the fraction of frames drawn over them (default 1; the rest ray-cast)")
    synth.add_argument("--nominal-paint-share", type=_number,
                       help="share of frames whose poles keep the nominal paint; the rest vary hue, saturation and "
                            f"value per band (default {SceneConfig.nominal_paint_share})")
    synth.add_argument("--far-share", type=_number,
                       help="share of frames whose poles all stand %g-%g m away, 6-18 px wide at 640x480 "
                            "(default 0: 0.4-9 m, log-uniform)" % SceneConfig.far_range_m)
    synth.add_argument("--preview", action="store_true", help="also write preview.png, a contact sheet with labels drawn")
    synth.add_argument("--workers", type=_whole_number(0), default=None, help="render processes (default: every core)")
    synth.add_argument("--force", action="store_true", help="replace --out if it exists")

    check = sub.add_parser("check", help="validate a dataset and print a summary and every problem")
    _add_dataset_argument(check, "dataset folder (with data.yaml) or Roboflow COCO export folder")
    check.add_argument("--fix", action="store_true", help="write a cleaned copy to --out (never in place)")
    check.add_argument("--out", type=Path, help="where --fix writes the cleaned copy")
    check.add_argument("--notes", action="store_true", help="also list notes (e.g. images without a label file)")
    check.add_argument("--force", action="store_true", help="replace --out if it exists")

    convert = sub.add_parser("convert", help="write any readable dataset (e.g. a COCO export) in the Roboflow YOLOv8 layout")
    _add_dataset_argument(convert, "dataset folder (with data.yaml) or Roboflow COCO export folder")
    convert.add_argument("--out", type=Path, required=True)
    convert.add_argument("--rename", action="append", metavar="OLD=NEW",
                         help="read the export's class OLD as landmark NEW (e.g. pink-blue=pb); repeat for each")
    convert.add_argument("--force", action="store_true")

    augment = sub.add_parser("augment", help="add N augmented copies of every training image (labels kept exact)")
    _add_dataset_argument(augment, "input dataset (never written)")
    augment.add_argument("--out", type=Path, required=True, help="output dataset folder")
    augment.add_argument("--copies", type=int, default=7, help="copies per training image (thesis: 7)")
    augment.add_argument("--seed", type=_whole_number(0), default=0)
    augment.add_argument("--ops", help=f"comma-separated operations to draw from (default all: {','.join(OPERATIONS)})")
    augment.add_argument("--config", type=Path, help="YAML with strength limits, e.g. `rotate_deg: 15`, `box_blur_px: 1.5`")
    defaults = AugmentConfig()
    for name, text in STRENGTH_FLAGS.items():
        augment.add_argument(f"--{name.replace('_', '-')}", type=_number, default=None,
                             help=f"{text} (default {getattr(defaults, name)})")
    augment.add_argument("--preview", action="store_true", help="write augment_preview.png: originals beside copies")
    augment.add_argument("--workers", type=_whole_number(0), default=None)
    augment.add_argument("--force", action="store_true")

    split = sub.add_parser("split", help="re-split a dataset, stratified so every class reaches every split")
    _add_dataset_argument(split, "dataset folder to re-split (never written)")
    split.add_argument("--out", type=Path, required=True)
    split.add_argument("--ratios", type=_number, nargs=3, default=(0.7, 0.2, 0.1), metavar=("TRAIN", "TEST", "VALID"),
                       help="fractions for train, test and valid (thesis: 0.7 0.2 0.1)")
    split.add_argument("--seed", type=_whole_number(0), default=0)
    split.add_argument("--force", action="store_true")

    train = sub.add_parser("train", help="train a YOLOv8 segmentation model on the CPU (offline, every core)")
    _add_dataset_argument(train, "dataset folder with data.yaml")
    train.add_argument("--out", type=Path, required=True, help="run folder (weights/best.pt, results.csv, curves)")
    train.add_argument("--model", help="yolov8n-seg (default), yolov8s-seg or yolov8m-seg")
    train.add_argument("--weights", help="checkpoint (or `poles train` run folder) to fine-tune from (default: the "
                                         "shipped pole model for yolov8n-seg), or `scratch` to train from the "
                                         "architecture alone")
    train.add_argument("--epochs", type=_whole_number(1), default=100,
                       help="epochs to train (default 100; --time overrides)")
    train.add_argument("--time", type=_number, help="train for this many hours instead (Ultralytics fits the epochs)")
    train.add_argument("--imgsz", type=_whole_number(32), default=640, help="training image size (default 640)")
    train.add_argument("--batch", type=_whole_number(1), default=8, help="images per batch (default 8)")
    train.add_argument("--patience", type=_whole_number(0), default=50,
                       help="stop after this many epochs without improvement (default 50; 0: never stop early)")
    train.add_argument("--seed", type=_whole_number(0), default=0, help="random seed (default 0)")
    train.add_argument("--threads", type=_threads,
                       help="torch threads: `shared` (default): every core, waiting threads sleep, so other programs "
                            "on the machine do not slow training down many times over; `all`: every core, waiting "
                            "threads spin (about 10 %% faster on an idle machine); a number; `auto` to re-time the "
                            "count while training")
    train.add_argument("--workers", type=_whole_number(0), default=0,
                       help="data-loader processes (default 0: best on 2 cores)")
    train.add_argument("--no-cache", action="store_true", help="do not cache decoded images in RAM")
    train.add_argument("--device", default="cpu",
                       help="cpu (default), a GPU index such as 0, several such as 0,1 (Ultralytics' DDP), or mps")
    train.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", dest="hyperparameters",
                       help="any other Ultralytics training argument, e.g. --set lr0=0.0002 --set mosaic=0; repeat "
                            "for each (checked by Ultralytics; the flags above cannot be set this way)")
    train.add_argument("--resume", action="store_true", help="continue the interrupted run in --out")

    export = sub.add_parser("export", help="export to ONNX (FP32, optional INT8), verified against PyTorch")
    export.add_argument("--weights", type=run_checkpoint, required=True,
                        help="trained checkpoint (best.pt), or the `poles train` run folder that holds it")
    export.add_argument("--out", type=Path, required=True,
                        help="ONNX file to write, e.g. model.onnx (INT8 goes beside it as *-int8.onnx)")
    export.add_argument("--imgsz", type=int, nargs=2, default=(480, 640), metavar=("HEIGHT", "WIDTH"),
                        help="network input (default 480 640: the Nao's frames without padding)")
    export.add_argument("--data", type=Path, help="dataset whose valid/test frames verify the export "
                                                  "(default: the one the model was trained on)")
    export.add_argument("--int8", action="store_true", help="also write a static INT8 copy")
    export.add_argument("--calib-data", type=Path, help="dataset whose training images calibrate INT8 (default --data)")
    export.add_argument("--reduce-range", action="store_true", help="7-bit INT8 weights, for x86 CPUs without VNNI")
    export.add_argument("--conf", type=_confidence, default=0.25, help="confidence threshold used when verifying")
    export.add_argument("--dynamic", action="store_true",
                        help="any input size (multiples of 32), so the front end can run on the band below the "
                             "horizon alone when it knows the camera pose")
    export.add_argument("--force", action="store_true", help="replace existing output files")

    soup = sub.add_parser("soup", help="blend two checkpoints of one network: (1 - alpha) * first + alpha * second")
    soup.add_argument("--weights", type=run_checkpoint, nargs=2, required=True, metavar=("FIRST", "SECOND"),
                      help="two checkpoints of one architecture (or `poles train` run folders), e.g. the shipped "
                           "model's and your fine-tune of it")
    soup.add_argument("--alpha", type=_number, required=True, help="the second checkpoint's share, 0-1")
    soup.add_argument("--out", type=Path, required=True, help="checkpoint to write (export it with `poles export`)")
    soup.add_argument("--force", action="store_true", help="replace an existing --out")

    calib = sub.add_parser("calibrate", help="fit range = a * px^b from poles of known distance")
    _add_dataset_argument(calib, "dataset whose annotations.json (or --truth CSV) gives each pole's true range")
    calib.add_argument("--out", type=Path, required=True, help="calibration.json to write")
    source = calib.add_mutually_exclusive_group()
    source.add_argument("--model", type=Path, help="measure the masks this ONNX model finds")
    source.add_argument("--from-labels", action="store_true", help="measure the labelled masks (default)")
    calib.add_argument("--truth", type=Path, help="CSV image,class,range_m instead of annotations.json")
    calib.add_argument("--plot", type=Path, help="write the fit plot (PNG)")
    calib.add_argument("--embed", type=Path, action="append", default=[], metavar="MODEL",
                       help="store the calibration in this ONNX model's metadata; repeat for each model that will "
                            "use it, e.g. the FP32 model and its INT8 copy")
    _add_input_width_argument(calib, "measure --model's masks as the robot will run it: ")
    calib.add_argument("--noise-data", type=Path, action="append", default=[], metavar="WALK",
                       help="frames of a walk with true ranges (`poles synth --walk`, or your own robot's with "
                            "annotations.json), measured like --data: the noise the filter is told (repeatable; "
                            "default: the walk floor measured with the shipped model)")
    calib.add_argument("--force", action="store_true")

    evaluate = sub.add_parser("evaluate", help="precision, recall and mask IoU per image on held-out frames")
    evaluate.add_argument("--model", action="append",
                          help="a .pt checkpoint (or its `poles train` run folder), an .onnx model, `shipped`, "
                               "`shipped-int8` or `colour-filter`; "
                               "repeat to compare several (default: the shipped model)")
    _add_dataset_argument(evaluate, "held-out frames with labels (dataset folder or COCO export)")
    evaluate.add_argument("--split", default="test", help="split to evaluate (default test)")
    evaluate.add_argument("--conf", type=_confidence,
                          help="confidence threshold for the counts (default: the model's own, else 0.5)")
    evaluate.add_argument("--calibration", type=Path, help="calibration.json for range errors "
                                                           "(default: the one embedded in the ONNX model; for the "
                                                           "colour filter, the shipped model's colour law)")
    _add_input_width_argument(evaluate, "a .pt checkpoint at 640 unless given; ONNX: ")
    evaluate.add_argument("--out", type=Path, required=True, help="folder for metrics.json, plots and FP/FN overlays")
    evaluate.add_argument("--force", action="store_true", help="replace --out if it holds files")

    slam = sub.add_parser("slam", help="run an EKF SLAM back end on a simulated walk, a UTIAS log or a recording")
    source = slam.add_mutually_exclusive_group(required=True)
    source.add_argument("--sim", choices=PATHS, help="simulated walk on the SPL field")
    source.add_argument("--utias", type=Path, help="UTIAS MRCLAM folder (Odometry.dat, Measurement.dat, ...)")
    source.add_argument("--frames", type=Path, help="recorded frames named <time>.jpg (with --odometry)")
    slam.add_argument("--odometry", type=Path, help="odometry CSV t,x,y,theta for --frames")
    slam.add_argument("--frontend", help="model.onnx, `shipped` or colour-filter: the image-level simulation / "
                                         "recording (default for --frames: the shipped model)")
    slam.add_argument("--calibration", type=Path, help="calibration.json (default: the one in the model; for "
                                                   "colour-filter, the shipped model's colour law)")
    _add_input_width_argument(slam)
    slam.add_argument("--conf", type=_confidence,
                      help="detections used from this confidence (default: the model's own threshold, else 0.85)")
    slam.add_argument("--no-camera-pose", action="store_true",
                      help="do not give the front end the camera's pose (rendered walk: the renderer's; recording: "
                           "camera_height,camera_pitch,camera_roll columns of the odometry CSV), so no ground-plane "
                           "gate and no foot-row range")
    slam.add_argument("--time-offset", type=_number, default=0.3,
                      help="frame time shift for recordings (thesis +0.3 s)")
    slam.add_argument("--backend", choices=("ekf", "fej", "oc"), default="oc",
                      help="linearisation: standard EKF, FEJ-EKF or OC-EKF (default, observability-constrained)")
    slam.add_argument("--association", choices=("nearest", "class"),
                      help="nearest: by geometry, the class as evidence (default); class: the class is the "
                           "landmark's identity (known correspondences; default for --utias, whose barcodes are)")
    slam.add_argument("--no-self-calibration", action="store_true",
                      help="do not estimate the odometry's stride and turn scales")
    slam.add_argument("--min-views", type=int, default=3, help="agreeing sightings before a landmark enters the map")
    slam.add_argument("--min-separation", type=_number, default=0.5, metavar="METRES",
                      help="no landmark enters the map this close to a mapped one: two poles never stand that close "
                           "(default 0.5; 0: off)")
    slam.add_argument("--outlier-filter", action="store_true", help="drop measurements 0.4 m / pi/3 off prediction")
    slam.add_argument("--gate", type=_number, default=9.21,
                      help="Mahalanobis gate on every update (chi-square, 2 dof; default 9.21 = 99 %%)")
    slam.add_argument("--no-gate", action="store_true", help="accept every associated measurement (the thesis)")
    slam.add_argument("--duration", type=_positive_number,
                      help="seconds of the walk or UTIAS log (sim default 90: once round and one more side; a log: "
                           "all of it)")
    slam.add_argument("--false-positive-rate", type=_number, default=0.05,
                      help="sim: share of frames with a one-off false positive")
    slam.add_argument("--confusion-rate", type=_number, default=0.0, help="sim: share of sightings given another class")
    slam.add_argument("--lookalikes", type=int, default=0,
                      help="sim: look-alike poles of a wrong class standing in the walk's area")
    slam.add_argument("--frame-rate", type=_number,
                      help=f"sim: frames per second the front end gets through, of the camera's {SimConfig.frame_hz:g} "
                           "(default all; e.g. 2.5 or 1.25): what a slower CPU affords, on the same walk")
    slam.add_argument("--odometry-bias", type=_number, default=1.25,
                      help="sim: reported stride per true stride (default 1.25: the Nao over-reports)")
    slam.add_argument("--map", metavar="CSV",
                      help="localise on a known map instead of building one: a CSV class,x,y (metres, the field's "
                           "frame) of where the poles stand, or `true` for a simulated walk's own; EKF localisation "
                           "with the odometry scales (--eif, --gate, --no-gate and --no-self-calibration apply; the "
                           "other SLAM options do not)")
    slam.add_argument("--eif", action="store_true", help="with --map: the information filter instead of the EKF")
    slam.add_argument("--start", type=_numbers("X,Y,THETA"), metavar="X,Y,THETA",
                      help="the filter's start pose (m, m, rad) in the map's frame (default: a simulated walk's true "
                           "start, a recording's first odometry pose, a UTIAS log's origin)")
    slam.add_argument("--start-std", type=_numbers("METRES,RADIANS", positive=True), metavar="METRES,RADIANS",
                      default=(0.01, 0.01),
                      help="how well the start is known (default 0.01,0.01; e.g. 0.2,0.2 for a robot placed by hand)")
    slam.add_argument("--seed", type=_whole_number(0), default=0)
    slam.add_argument("--compare", type=_whole_number(1), metavar="SEEDS",
                      help="also run every back end (and, on a simulated walk, the GTSAM smoother reference) on "
                           "SEEDS seeds and print the comparison table")
    slam.add_argument("--out", type=Path, required=True, help="folder for metrics.json, path.csv, map.json and plots")
    slam.add_argument("--force", action="store_true", help="replace --out if it holds files")

    predict = sub.add_parser("predict", help="pre-label new frames for Roboflow, or draw a model's view on a video")
    source = predict.add_mutually_exclusive_group(required=True)
    source.add_argument("--images", type=Path,
                        help="folder of unlabelled frames (subfolders too): write pre-annotations to --out")
    source.add_argument("--video", type=Path, help="video file or folder of frames in order: write an overlay MP4")
    predict.add_argument("--out", type=Path, required=True, help="dataset folder (--images) or video.mp4 (--video)")
    predict.add_argument("--model", type=Path, help="ONNX model (default: the shipped model)")
    predict.add_argument("--conf", type=_confidence, help="confidence threshold (default: the model's own)")
    predict.add_argument("--format", choices=("yolov8", "coco"), default="yolov8", help="pre-annotation layout")
    _add_input_width_argument(predict, "with --video, to see what a robot running it smaller sees: ")
    predict.add_argument("--force", action="store_true")

    demo = sub.add_parser("demo", help="run the whole pipeline on a synthetic dataset and write report.html")
    demo.add_argument("--out", type=Path, default=Path("runs/demo"))
    demo.add_argument("--budget", choices=("fast", "full"), default="fast",
                      help="fast: about 15 minutes on two cores (default); full: the thesis's settings (days)")
    demo.add_argument("--seed", type=_whole_number(0), default=0)
    demo.add_argument("--threads", choices=("shared", "all"),
                      help="shared (default): every core, waiting threads sleep, so other programs do not slow "
                           "training down many times over; all: every core, waiting threads spin (about 10 %% faster "
                           "on an idle machine)")

    for command in sub.choices.values():
        command.add_argument("--debug", action="store_true", help="show the traceback of an unexpected error")
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run one ``poles`` command; bad input ends in one line on stderr and exit code 2, never a traceback."""
    args = build_parser().parse_args(argv)

    def command() -> int:
        if hasattr(args, "data_option"):
            args.data = _one_dataset(args)
        return COMMANDS[args.command](args)

    return run_command(args.command, command, debug=args.debug)


def _synth(args: argparse.Namespace) -> int:
    from detector.synth.backdrops import scan_backdrops
    from detector.synth.generate import DEFAULT_SYNTH_IMAGES, SynthJob, generate_dataset
    from detector.synth.walk import walk_frame_steps

    images = args.images if args.images is not None else (
        len(walk_frame_steps(args.walk, args.seed)) if args.walk else DEFAULT_SYNTH_IMAGES)
    if images < 1:
        raise ValueError("--images must be at least 1")
    options = {name: value for name, value in (("nominal_paint_share", args.nominal_paint_share),
                                               ("far_share", args.far_share)) if value is not None}
    flags = " and ".join("--" + name.replace("_", "-") for name in options)
    if args.walk and options:
        raise ValueError(f"--walk places and paints its poles as `poles slam` renders them: leave out {flags}")
    if args.calibration_shots and options:
        raise ValueError(f"--calibration-shots stands one nominally painted pole at each set distance: leave out {flags}")
    config = SceneConfig(**options)
    backgrounds = scan_backdrops(args.backgrounds) if args.backgrounds is not None else ()
    job = SynthJob(images, args.seed, *args.size, hfov_deg=args.hfov, calibration_shots=args.calibration_shots,
                   backgrounds=backgrounds, backdrop_share=args.backdrop_share, walk=args.walk, config=config)
    out = generate_dataset(args.out, job, workers=args.workers, preview=args.preview, force=args.force,
                           protect=_existing(args.backgrounds))
    print(f"wrote {images} images to {out}")
    return 0


def _check(args: argparse.Namespace) -> int:
    from detector.datasets.check import check_dataset, listing_path, print_report, write_fixed_copy
    from detector.datasets.io import check_output_folder

    if args.fix and args.out is None:
        raise ValueError("--fix needs --out CLEAN: the cleaned copy is never written in place")
    report = check_dataset(args.data)
    if args.fix:  # refused before the list of problems is written beside it
        check_output_folder(args.out, args.force, report.dataset.input_folders())
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
    print(f"train images: {summary['train_images_in']} -> {summary['train_images_out']}; instances in copies kept "
          f"{summary['instances_kept']}, dropped {summary['instances_dropped']} (clipped away or too small)")
    print("operations used: " + (", ".join(f"{k} {v}" for k, v in sorted(summary["operations"].items()))
                                 or "none"))
    if "preview" in summary:
        print(f"preview: {summary['preview']}")
    return 0


def _split(args: argparse.Namespace) -> int:
    from detector.datasets.split import RATIO_ORDER, split_dataset

    counts = split_dataset(args.data, args.out, tuple(args.ratios), seed=args.seed, force=args.force)
    total = sum(args.ratios)
    if abs(total - 1) > 1e-6:  # the split divides by the sum; say so rather than let 0.7 0.2 0.2 pass unnoticed
        shares = ", ".join(f"{split} {100 * r / total:.0f} %" for split, r in zip(RATIO_ORDER, args.ratios))
        print(f"--ratios sum to {total:g}, so they were used as shares: {shares}")
    print("images per split: " + ", ".join(f"{k} {v}" for k, v in counts.items()))
    return 0


def _choose_wait_policy(threads: int | str | None) -> None:
    """Let OpenMP threads sleep while they wait, by default (None) and for ``--threads shared``; must run before
    torch loads. Only an explicit ``--threads shared`` says so when it came too late (a caller that loaded torch)."""
    if threads not in (None, "shared"):
        return
    if not sleep_while_waiting() and threads == "shared":
        print("--threads shared: torch was loaded already, OpenMP keeps its wait policy", file=sys.stderr)


def _train(args: argparse.Namespace) -> int:
    _choose_wait_policy(args.threads)
    from detector.training.starting_point import starting_point
    from detector.training.train import TrainSettings, parse_hyperparameters, summarise_run, train_model

    if args.resume and args.hyperparameters:
        raise ValueError("--set with --resume: a resumed run keeps the arguments it started with - drop --set")
    model, weights = (args.model or "", None) if args.resume else starting_point(args.model, args.weights)
    threads = args.threads if isinstance(args.threads, int) else None
    settings = TrainSettings(model=model or "yolov8n-seg", epochs=args.epochs, imgsz=args.imgsz, batch=args.batch,
                             patience=args.patience, seed=args.seed, threads=threads,
                             adaptive_threads=args.threads == "auto", workers=args.workers,
                             cache=not args.no_cache, time_hours=args.time, device=args.device,
                             hyperparameters=parse_hyperparameters(args.hyperparameters))
    run = train_model(args.data, args.out, settings, weights=weights, resume=args.resume)
    best = summarise_run(run)
    print(f"best epoch {best['best_epoch']} of {best['epochs']} (validation): mask mAP50 {best['mAP50(M)']:.3f}, "
          f"mAP50-95 {best['mAP50-95(M)']:.3f}; weights {run / 'weights' / 'best.pt'}; curves {run / 'training_curves.png'}")
    return 0


def _export(args: argparse.Namespace) -> int:
    from export.run import ExportJob, print_report, run_export

    job = ExportJob(args.weights, args.out, tuple(args.imgsz), args.data, args.int8, args.calib_data,
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


def _evaluate(args: argparse.Namespace) -> int:
    from calibration.run import load_calibration
    from detector.datasets.io import output_folder
    from detector.evaluation.predictors import make_predictor
    from detector.evaluation.run import evaluate, print_metrics

    calibration = load_calibration(args.calibration) if args.calibration else None
    rows = []
    models = args.model or ["shipped"]
    predictors = [make_predictor(model, args.imgsz, calibration) for model in models]  # every model checked first
    for predictor, label in zip(predictors, _column_labels(models, [p.name for p in predictors])):
        predictor.name = label
    with output_folder(args.out, args.force, _existing(args.data, args.calibration, *map(Path, models))) as folder:
        for predictor in predictors:
            out = folder / predictor.name if len(models) > 1 else folder
            conf = args.conf if args.conf is not None else predictor.operating_conf or FALLBACK_CONF
            rows.append(evaluate(predictor, args.data, out, args.split, conf))
    print_metrics(rows)
    print(f"wrote {args.out} (metrics.json, per_image.png, sweep.png, confusion.png, recall_by_width.png, errors/)")
    return 0


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
        print(f"pre-labelled {result['frames']} frames ({result['poles']} poles, {result['empty']} without) at conf "
              f"{result['conf']:.2f}: {result['out']} - upload it to Roboflow as pre-annotations, correct, export")
    else:
        result = overlay_video(args.video, args.out, args.model, args.conf, args.force, input_width=args.imgsz)
        print(f"wrote {result['frames']} frames to {result['video']} and the contact sheet {result['sheet']}"
              + ("" if result["ranges"] else " (no ranges drawn: the model has no calibration for this input width)"))
    return 0


def _run_summary(metrics: dict, localising: bool) -> str:
    """One line of a run's figures: its errors where there was truth to score against, else what it saw."""
    errors = [f"{key} mean {metrics[key]['mean']:.3f} m" for key in ("robot_error", "landmark_error", "odometry_error")
              if key in metrics]
    if errors:
        return ", ".join(errors)
    counts = metrics["counts"]
    mapped = "" if localising else f", {counts['initialised']} landmarks mapped"
    return f"no truth to score against: {counts['accepted']} sightings accepted{mapped}"


def _slam(args: argparse.Namespace) -> int:
    from dataclasses import replace

    import numpy as np

    from calibration.run import load_calibration
    from detector.datasets.io import output_folder
    from detector.slam.comparison import BACKENDS, compare_backends, print_comparison
    from detector.slam.outputs import write_outputs
    from detector.slam.reference import smooth
    from detector.slam.sequences import FrontEnd, read_pole_map, recorded_sequence, sim_sequence, utias_sequence
    from naoslam.atomic import write_json
    from naoslam.ekf_slam import SlamConfig
    from naoslam.runner import LocalisationConfig, run_slam

    calibration = load_calibration(args.calibration) if args.calibration else None
    frontend = args.frontend or ("shipped" if args.frames else None)
    if args.imgsz is not None and frontend in (None, "colour-filter"):
        raise ValueError("--imgsz is a model's input width: give --frontend model.onnx or shipped")
    front_end = FrontEnd(frontend, calibration, args.conf, args.imgsz) if frontend else None
    if args.sim:
        def make(seed: int):
            sim = SimConfig(path=args.sim, duration_s=90.0 if args.duration is None else args.duration, seed=seed,
                            false_positive_rate=args.false_positive_rate, confusion_rate=args.confusion_rate,
                            lookalikes=args.lookalikes, stride_scale=args.odometry_bias,
                            front_end_hz=args.frame_rate)
            return sim_sequence(sim, front_end, camera_pose=not args.no_camera_pose)
    elif args.utias:
        def make(seed: int):
            return utias_sequence(args.utias, args.duration)
    else:
        if not args.odometry:
            raise ValueError("--frames needs --odometry: a CSV t,x,y,theta of the same recording")
        if args.duration is not None:
            raise ValueError("--duration is for --sim and --utias: a recording runs whole - give --frames a folder "
                             "of the part you want")

        def make(seed: int):
            return recorded_sequence(args.frames, args.odometry, front_end, args.time_offset,
                                     camera_pose=not args.no_camera_pose)
    gate = None if args.no_gate else args.gate
    if args.map:
        if args.map == "true" and not args.sim:
            raise ValueError("--map true is a simulated walk's own map: give --sim, or a CSV class,x,y of where your "
                             "poles stand")
        config = LocalisationConfig(information_form=args.eif, self_calibrate=not args.no_self_calibration,
                                    gate=gate, landmarks=None if args.map == "true" else read_pole_map(args.map))
    elif args.eif:
        raise ValueError("--eif is a localiser: give --map with where the poles stand")
    else:
        association = args.association or ("class" if args.utias else "nearest")
        config = SlamConfig(linearisation={"ekf": "standard"}.get(args.backend, args.backend),
                            outlier_filter=args.outlier_filter, gate=gate, min_views=args.min_views,
                            min_separation_m=args.min_separation, association=association,
                            self_calibrate=not args.no_self_calibration)
    map_file = Path(args.map) if args.map and args.map != "true" else None
    inputs = (args.utias, args.frames, args.odometry, args.calibration, Path(frontend) if frontend else None, map_file)
    start_std = (args.start_std[0], args.start_std[0], args.start_std[1])
    with output_folder(args.out, args.force, _existing(*inputs)) as out:
        sequence = make(args.seed)
        if args.start is not None:
            sequence = replace(sequence, start=np.array(args.start))
        metrics = write_outputs(run_slam(sequence, config, start_std), sequence, out)
        rows = None
        if args.compare:
            seeds = list(range(args.seed, args.seed + (args.compare if args.sim else 1)))
            reference = smooth if args.sim and not front_end else None
            rows = compare_backends(lambda s: sequence if s == args.seed else make(s), seeds, BACKENDS, reference)
            write_json(out / "comparison.json", rows)
    print(f"{config.label} on {sequence.name}: {_run_summary(metrics, localising=bool(args.map))}; wrote {args.out}")
    if rows is not None:
        print_comparison(rows, f"back ends on {sequence.name} ({len(seeds)} seed(s))")
    return 0


def _demo(args: argparse.Namespace) -> int:
    _choose_wait_policy(args.threads)
    from detector.demo.pipeline import BUDGETS, run_demo

    return run_demo(args.out, BUDGETS[args.budget], args.seed)


COMMANDS = {"synth": _synth, "check": _check, "convert": _convert, "augment": _augment, "split": _split,
            "train": _train, "export": _export, "soup": _soup, "calibrate": _calibrate, "evaluate": _evaluate,
            "slam": _slam, "predict": _predict, "demo": _demo}

if __name__ == "__main__":
    sys.exit(main())
