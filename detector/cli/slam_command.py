"""``poles slam``: a SLAM or localisation back end on a simulated walk, a UTIAS log or a recording."""
from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from detector.cli.arguments import (add_input_width_argument, confidence, existing, finite_number, flags_for,
                                    number_list, positive_number, whole_number)
from naoslam.ekf_slam import SlamConfig
from naoslam.shipped import COLOUR_FILTER
from naoslam.sim import PATHS, SimConfig

if TYPE_CHECKING:  # the front ends and the runner load when a run needs them, not with every `poles` command
    from detector.slam.sequences import FrontEndSpec
    from detector.slam.figures import RunFigures
    from naoslam.runner import LocalisationConfig, Sequence

#: The defaults every flag below shows and falls back to: the runtime's own.
SLAM, SIM = SlamConfig(), SimConfig()
#: The flag of each runtime parameter, for the runtime's messages (``flags_for``).
FLAGS = {"min_views": "--min-views", "min_separation_m": "--min-separation", "gate": "--gate",
         "duration_s": "--duration", "stride_scale": "--odometry-bias", "lookalikes": "--lookalikes",
         "false_positive_rate": "--false-positive-rate", "confusion_rate": "--confusion-rate",
         "front_end_hz": "--frame-rate"}


def add_parsers(sub: argparse._SubParsersAction) -> None:
    """Add the `slam` command to ``sub`` (``run``: the function that runs it)."""
    slam = sub.add_parser("slam", help="run an EKF SLAM back end on a simulated walk, a UTIAS log or a recording")
    source = slam.add_mutually_exclusive_group(required=True)
    source.add_argument("--sim", choices=PATHS, help="simulated walk on the SPL field")
    source.add_argument("--utias", type=Path, help="UTIAS MRCLAM folder (Odometry.dat, Measurement.dat, ...)")
    source.add_argument("--frames", type=Path, help="recorded frames named <time>.jpg (with --odometry)")
    slam.add_argument("--odometry", type=Path, help="odometry CSV t,x,y,theta for --frames")
    slam.add_argument("--frontend", help="model.onnx, `shipped`, `shipped-robot` or colour-filter: the image-level "
                                         "simulation / recording (default for --frames: the shipped model)")
    slam.add_argument("--calibration", type=Path, help="calibration.json (default: the one in the model; for "
                                                   "colour-filter, the shipped model's colour law)")
    add_input_width_argument(slam)
    slam.add_argument("--conf", type=confidence,
                      help="detections used from this confidence (default: the model's own threshold, else 0.85)")
    slam.add_argument("--maybe-conf", type=confidence, metavar="CONF",
                      help="also pass detections from CONF up to the threshold, as sightings the filter takes only "
                           "where they confirm a mapped landmark of their class inside the gate (never to map one)")
    slam.add_argument("--no-camera-pose", action="store_true",
                      help="do not give the front end the camera's pose (rendered walk: the renderer's; recording: "
                           "camera_height,camera_pitch,camera_roll columns of the odometry CSV), so no ground-plane "
                           "gate and no foot-row range")
    slam.add_argument("--time-offset", type=finite_number, default=0.3,
                      help="frame time shift for recordings (thesis +0.3 s)")
    slam.add_argument("--backend", choices=("ekf", "fej", "oc"), default="oc",
                      help="linearisation: standard EKF, FEJ-EKF or OC-EKF (default, observability-constrained)")
    slam.add_argument("--association", choices=("nearest", "class"),
                      help="nearest: by geometry, the class as evidence (default); class: the class is the "
                           "landmark's identity (known correspondences; default for --utias, whose barcodes are)")
    slam.add_argument("--no-self-calibration", action="store_true",
                      help="do not estimate the odometry's stride and turn scales")
    slam.add_argument("--min-views", type=int, default=SLAM.min_views,
                      help=f"agreeing sightings before a landmark enters the map (default {SLAM.min_views})")
    slam.add_argument("--min-separation", type=finite_number, default=SLAM.min_separation_m, metavar="METRES",
                      help="no landmark enters the map this close to a mapped one: two poles never stand that close "
                           f"(default {SLAM.min_separation_m:g}; 0: off)")
    slam.add_argument("--outlier-filter", action="store_true", help="drop measurements 0.4 m / pi/3 off prediction")
    slam.add_argument("--gate", type=finite_number, default=SLAM.gate,
                      help=f"Mahalanobis gate on every update (chi-square, 2 dof; default {SLAM.gate:g} = 99 %%)")
    slam.add_argument("--no-gate", action="store_true", help="accept every associated measurement (the thesis)")
    slam.add_argument("--duration", type=positive_number,
                      help=f"seconds of the walk or UTIAS log (sim default {SIM.duration_s:g}: once round and one "
                           "more side; a log: all of it)")
    slam.add_argument("--false-positive-rate", type=finite_number, default=SIM.false_positive_rate,
                      help=f"sim: share of frames with a one-off false positive (default {SIM.false_positive_rate:g})")
    slam.add_argument("--confusion-rate", type=finite_number, default=SIM.confusion_rate,
                      help=f"sim: share of sightings given another class (default {SIM.confusion_rate:g})")
    slam.add_argument("--lookalikes", type=int, default=SIM.lookalikes,
                      help="sim: look-alike poles of a wrong class standing in the walk's area")
    slam.add_argument("--frame-rate", type=finite_number,
                      help=f"sim: frames per second the front end gets through, of the camera's {SimConfig.frame_hz:g} "
                           "(default all; e.g. 2.5 or 1.25): what a slower CPU affords, on the same walk")
    slam.add_argument("--odometry-bias", type=finite_number, default=SIM.stride_scale,
                      help=f"sim: reported stride per true stride (default {SIM.stride_scale:g}: the Nao "
                           "over-reports)")
    slam.add_argument("--map", metavar="CSV",
                      help="localise on a known map instead of building one: a CSV class,x,y (metres, the field's "
                           "frame) of where the poles stand, or `true` for a simulated walk's own; EKF localisation "
                           "with the odometry scales (--eif, --gate, --no-gate and --no-self-calibration apply; the "
                           "other SLAM options do not)")
    slam.add_argument("--eif", action="store_true", help="with --map: the information filter instead of the EKF")
    slam.add_argument("--start", type=number_list("X,Y,THETA"), metavar="X,Y,THETA",
                      help="the filter's start pose (m, m, rad) in the map's frame (default: a simulated walk's true "
                           "start, a recording's first odometry pose, a UTIAS log's origin)")
    slam.add_argument("--start-std", type=number_list("METRES,RADIANS", positive=True), metavar="METRES,RADIANS",
                      default=(0.01, 0.01),
                      help="how well the start is known (default 0.01,0.01; e.g. 0.2,0.2 for a robot placed by hand)")
    slam.add_argument("--seed", type=whole_number(0), default=0)
    slam.add_argument("--compare", type=whole_number(1), metavar="SEEDS",
                      help="also run every back end (and, on a simulated walk, the GTSAM smoother reference) on "
                           "SEEDS seeds and print the comparison table")
    slam.add_argument("--out", type=Path, required=True, help="folder for metrics.json, path.csv, map.json and plots")
    slam.add_argument("--force", action="store_true", help="replace --out if it holds files")
    slam.set_defaults(run=_slam)


def _run_summary(figures: RunFigures, localising: bool) -> str:
    """One line of a run's figures: its errors where there was truth to score against, else what it saw."""
    errors = [f"{name} error mean {value:.3f} m" for name, value in figures.errors().items()]
    if errors:
        return ", ".join(errors)
    mapped = "" if localising else f", {figures.initialised} landmark{'' if figures.initialised == 1 else 's'} mapped"
    return f"no truth to score against: {figures.accepted} sightings accepted{mapped}"


def _slam(args: argparse.Namespace) -> int:
    from dataclasses import replace

    import numpy as np

    from detector.model_files import load_calibration
    from detector.outputs import output_folder
    from detector.slam.comparison import BACKENDS, compare_backends, print_comparison
    from detector.slam.outputs import write_outputs
    from detector.slam.reference import smooth
    from detector.slam.sequences import FrontEndSpec
    from detector.formats import write_record
    from naoslam.runner import run_slam

    if args.utias and (args.frontend or args.imgsz is not None or args.conf is not None or args.maybe_conf):
        raise ValueError("--frontend, --imgsz, --conf and --maybe-conf choose what reads camera frames; a UTIAS log "
                         "holds ranges and bearings already measured, no frames - leave them out, or give --frames "
                         "or --sim")
    calibration = load_calibration(args.calibration) if args.calibration else None
    frontend = args.frontend or ("shipped" if args.frames else None)
    if args.imgsz is not None and frontend in (None, COLOUR_FILTER):
        raise ValueError("--imgsz is a model's input width: give --frontend model.onnx or shipped")
    if args.maybe_conf is not None and not frontend:
        raise ValueError("--maybe-conf is a front end's lower threshold: give --frontend (or --frames)")
    if args.maybe_conf is not None and args.conf is not None and args.maybe_conf > args.conf:
        raise ValueError(f"--maybe-conf {args.maybe_conf:g} lies above --conf {args.conf:g}: the maybe tier takes "
                         "the sightings under the threshold - give a --maybe-conf at most --conf")
    front_end = FrontEndSpec(frontend, calibration, args.conf, args.imgsz, args.maybe_conf) if frontend else None
    make = _sequence_maker(args, front_end)
    with flags_for(FLAGS):
        config = _filter_config(args)
    map_file = Path(args.map) if args.map and args.map != "true" else None
    inputs = (args.utias, args.frames, args.odometry, args.calibration, Path(frontend) if frontend else None, map_file)
    start_std = (args.start_std[0], args.start_std[0], args.start_std[1])
    with output_folder(args.out, args.force, existing(*inputs), "slam run") as out:
        sequence = make(args.seed)
        if args.start is not None:
            sequence = replace(sequence, start=np.array(args.start))
        metrics = write_outputs(run_slam(sequence, config, start_std), sequence, out)
        rows = None
        if args.compare:
            seeds = list(range(args.seed, args.seed + (args.compare if args.sim else 1)))
            reference = smooth if args.sim and not front_end else None
            rows = compare_backends(lambda s: sequence if s == args.seed else make(s), seeds, BACKENDS, reference)
            write_record(out / "comparison.json", "slam comparison", [row.to_json() for row in rows])
    print(f"{config.label} on {sequence.name}: {_run_summary(metrics, localising=bool(args.map))}; wrote {args.out}")
    if rows is not None:
        print_comparison(rows, f"back ends on {sequence.name} ({len(seeds)} seed(s))")
    return 0


def _sequence_maker(args: argparse.Namespace, front_end: FrontEndSpec | None) -> Callable[[int], Sequence]:
    """What the filter runs on, per seed: a simulated walk, a UTIAS log or a recording (the same for every seed)."""
    from detector.slam.sequences import recorded_sequence, sim_sequence, utias_sequence

    if args.sim:
        def make(seed: int) -> Sequence:
            with flags_for(FLAGS):
                sim = SimConfig(path=args.sim, duration_s=SIM.duration_s if args.duration is None else args.duration,
                                seed=seed, false_positive_rate=args.false_positive_rate,
                                confusion_rate=args.confusion_rate, lookalikes=args.lookalikes,
                                stride_scale=args.odometry_bias, front_end_hz=args.frame_rate)
            return sim_sequence(sim, front_end, camera_pose=not args.no_camera_pose)
        return make
    if args.utias:
        def make_utias(seed: int) -> Sequence:
            with flags_for(FLAGS):
                return utias_sequence(args.utias, args.duration)
        return make_utias
    if not args.odometry:
        raise ValueError("--frames needs --odometry: a CSV t,x,y,theta of the same recording")
    if args.duration is not None:
        raise ValueError("--duration is for --sim and --utias: a recording runs whole - give --frames a folder "
                         "of the part you want")
    return lambda seed: recorded_sequence(args.frames, args.odometry, front_end, args.time_offset,
                                          camera_pose=not args.no_camera_pose)


def _filter_config(args: argparse.Namespace) -> SlamConfig | LocalisationConfig:
    """The back end the flags ask for: EKF or EIF localisation on a known map (``--map``), else EKF SLAM."""
    from detector.slam.sequences import read_pole_map
    from naoslam.runner import LocalisationConfig

    gate = None if args.no_gate else args.gate
    if args.map:
        if args.map == "true" and not args.sim:
            raise ValueError("--map true is a simulated walk's own map: give --sim, or a CSV class,x,y of where your "
                             "poles stand")
        return LocalisationConfig(information_form=args.eif, self_calibrate=not args.no_self_calibration,
                                  gate=gate, landmarks=None if args.map == "true" else read_pole_map(args.map))
    if args.eif:
        raise ValueError("--eif is a localiser: give --map with where the poles stand")
    association = args.association or ("class" if args.utias else "nearest")
    return SlamConfig(linearisation={"ekf": "standard"}.get(args.backend, args.backend),
                      outlier_filter=args.outlier_filter, gate=gate, min_views=args.min_views,
                      min_separation_m=args.min_separation, association=association,
                      self_calibrate=not args.no_self_calibration)
