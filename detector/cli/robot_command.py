"""``poles train-robot``: the robot's two-stage front end trained from annotated frames on the CPU - crops of the
finder's candidates, the crop network trained on them (and, if asked, on its own second looks), exported to ONNX and
checked against PyTorch, a preclassifier trained to spare it most windows, its operating threshold chosen on the
valid frames."""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from detector.cli.arguments import existing, minutes_number, whole_number
from detector.crops.settings import CropTrainSettings

#: ``poles train-robot``'s defaults, read by its help.
DEFAULTS = CropTrainSettings()


def add_parsers(sub: argparse._SubParsersAction) -> None:
    """Add the ``train-robot`` command to ``sub``."""
    robot = sub.add_parser("train-robot", help="train the robot's two-stage front end (candidates + crop network) "
                                               "on the CPU")
    robot.add_argument("data", type=Path, nargs="+",
                       help="dataset folders with data.yaml: train split for training, valid split for the best "
                            "epoch and the threshold")
    robot.add_argument("--out", type=Path, required=True,
                       help="run folder: poles-robot.pt, poles-robot.onnx, history.json, training_curves.png")
    robot.add_argument("--weights", type=Path, help="a poles-robot.pt to go on training from (default: from scratch)")
    robot.add_argument("--teacher", type=Path,
                       help="a poles-robot.pt whose class scores the new network learns beside the labels "
                            "(distillation; e.g. detector/weights/poles-robot.pt, the shipped network)")
    robot.add_argument("--epochs", type=whole_number(0), default=DEFAULTS.epochs,
                       help=f"epochs over the crops (default {DEFAULTS.epochs}; 0 with --weights and "
                            "--second-look-epochs: only the second looks)")
    robot.add_argument("--second-look-epochs", type=whole_number(0), default=DEFAULTS.second_look_epochs,
                       help="epochs more with the crops of the second looks the trained network takes added "
                            f"(default {DEFAULTS.second_look_epochs}: none; 6 to use them)")
    robot.add_argument("--preclassifier-epochs", type=whole_number(0), default=DEFAULTS.preclassifier_epochs,
                       help="epochs of the preclassifier that rejects most windows before the crop network sees them, "
                            f"stored in the model (default {DEFAULTS.preclassifier_epochs}; 0: none, every window "
                            "goes through the crop network)")
    robot.add_argument("--minutes", type=minutes_number,
                       help="stop training after this many minutes even if epochs are left")
    robot.add_argument("--seed", type=whole_number(0), default=DEFAULTS.seed,
                       help=f"random seed (default {DEFAULTS.seed})")
    robot.add_argument("--threads", type=whole_number(1), default=DEFAULTS.threads,
                       help=f"torch threads (default {DEFAULTS.threads})")
    robot.add_argument("--force", action="store_true", help="replace an earlier --out of poles")
    robot.set_defaults(run=_train_robot)


def _train_robot(args: argparse.Namespace) -> int:
    from detector.robot_training import train_robot_front_end

    settings = CropTrainSettings(epochs=args.epochs, seed=args.seed, threads=args.threads, minutes=args.minutes,
                                 second_look_epochs=args.second_look_epochs,
                                 preclassifier_epochs=args.preclassifier_epochs)
    result = train_robot_front_end(args.data, args.out, settings, args.weights, args.force,
                                   protect=existing(*args.data, args.weights, args.teacher), teacher=args.teacher)
    print(json.dumps(result.to_json(), indent=1))
    return 0
