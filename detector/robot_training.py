"""The robot front end's whole training recipe, from annotated frames to a verified ONNX file with its threshold:
crops of every dataset's train and valid splits, the crop network trained (or trained on from a checkpoint), if asked
a few epochs more with the second looks its own first look takes added, the export checked against PyTorch, the
preclassifier trained on the same crops and stored in the file, and the operating threshold the best F1 on the valid
frames (boxes matched by IoU) with the preclassifier in place, as the robot runs it. Everything lands in the run
folder at once, or nothing does."""
from __future__ import annotations

import os
import platform
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path

from detector.crops.curves import plot_crop_history
from detector.crops.export import export_crop_network
from detector.crops.network import CROP_SIZE_WH, PoleCropNet
from detector.crops.preclassifier import (PRECLASSIFIER_SIZE_WH, PreclassifierResult, preclassifier_onnx,
                                          train_preclassifier)
from detector.crops.samples import NO_POLE, CropSet, crops_of_dataset
from detector.crops.second_look import second_look_crops
from detector.crops.settings import CropTrainSettings
from detector.crops.train import EpochResult, load_checkpoint, save_checkpoint, train_crop_network
from detector.datasets.intake import open_dataset
from detector.datasets.model import Dataset
from detector.outputs import check_output_folder, output_folder
from detector.datasets.truth import ImageTruth, load_camera_poses, load_truth
from detector.evaluation.counting import best_threshold, confidence_sweep
from detector.evaluation.predictors import RuntimePredictor
from detector.evaluation.run import evaluate_frames
from detector.formats import write_record
from detector.model_files import add_metadata
from detector.records import JsonRecord
from naoslam.perception.preclassifier import PRECLASSIFIER_KEY, preclassifier_entry
from naoslam.perception.two_stage import CropDetector

#: The files a run folder holds.
CHECKPOINT, MODEL = "poles-robot.pt", "poles-robot.onnx"
#: The kind of output a run folder is (``detector.outputs``).
RUN_KIND = "robot front end run"
#: The threshold a model is exported at before the valid frames choose its own.
EXPORT_CONF = 0.5
#: The second-look epochs learn at this share of the first epochs' rate, from the train crops and every
#: second-look crop this many times over.
SECOND_LOOK_LEARNING_RATE_SHARE = 1 / 3
SECOND_LOOK_REPEAT = 2


def machine() -> str:
    """This machine in a few words: its cores and processor."""
    try:
        name = next(line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
                    if line.startswith("model name"))
    except (OSError, StopIteration):
        name = platform.processor() or platform.machine()
    return f"{os.cpu_count()} cores, {name}"


def crop_sets(datasets: list[Dataset], split: str, seed: int, progress: bool = True,
              size_wh: tuple[int, int] = CROP_SIZE_WH) -> CropSet:
    """The crops of one split of every dataset, cut at ``size_wh`` (the same windows at any size, for one seed)."""
    return CropSet.concatenate([crops_of_dataset(dataset, (split,), size_wh, seed=seed + i, progress=progress)
                                for i, dataset in enumerate(datasets)])


def open_training_data(data: list[Path], progress: bool = True) -> list[tuple[Dataset, dict[str, ImageTruth]]]:
    """Every dataset through the intake every command uses (``poles check``'s rules, images decoded) with its truth,
    so that whatever refuses it does so before the crops are cut and the network trained."""
    datasets = [open_dataset(root, progress=progress) for root in data]
    return [(dataset, load_truth(dataset)) for dataset in datasets]


def valid_threshold(model: Path, opened: list[tuple[Dataset, dict[str, ImageTruth]]],
                    progress: bool = True) -> tuple[float, float]:
    """The confidence threshold of the best F1 over every dataset's valid frames (each with its camera pose where
    annotations.json records one, as on the robot), and that F1."""
    predictor = RuntimePredictor(model)
    images = []
    for dataset, truth in opened:
        images += evaluate_frames(predictor, dataset.split("valid"), truth, "choosing the threshold",
                                  progress, poses=load_camera_poses(dataset))
    sweep = confidence_sweep(images)
    threshold = best_threshold(sweep) or EXPORT_CONF
    return threshold, max(point.f1 for point in sweep)


@dataclass(frozen=True)
class RobotTraining(JsonRecord):
    """What ``poles train-robot`` made: the crops it learnt from, its best epoch, the ONNX model and its threshold."""

    data: tuple[Path, ...]
    train_crops: int
    valid_crops: int
    pole_crops: int
    #: Second-look crops added to the train crops (each ``SECOND_LOOK_REPEAT`` times); 0 where none were.
    second_look_crops: int
    #: The best epoch of the last stage (the second looks' where they ran), on that stage's valid crops; None where
    #: only a preclassifier was trained.
    best_epoch: EpochResult | None
    epochs: int
    minutes: float
    #: Largest output difference between the ONNX model and PyTorch on valid crops.
    onnx_difference: float
    #: Best-F1 threshold on the valid frames, and that F1.
    operating_conf: float
    valid_f1: float
    settings: CropTrainSettings
    #: The preclassifier stored in the model (None: none was trained).
    preclassifier: PreclassifierResult | None
    #: The checkpoint it started from (None: from scratch).
    weights: Path | None
    model: Path
    #: The checkpoint whose class scores the network learnt beside the labels (None: the labels alone).
    teacher: Path | None = None


def train_robot_front_end(data: list[Path], out: Path, settings: CropTrainSettings = CropTrainSettings(),
                          weights: Path | None = None, force: bool = False, protect: tuple[Path, ...] = (),
                          progress: bool = True, teacher: Path | None = None) -> RobotTraining:
    """Train the crop network on ``data`` into the run folder ``out`` (learning the class scores of the crop
    network in the ``teacher`` checkpoint too, where one is given); returns its summary (also in history.json)."""
    data = [Path(root) for root in data]
    opened = open_training_data(data, progress)
    datasets = [dataset for dataset, _ in opened]
    inputs = (*protect, *(folder for dataset in datasets for folder in dataset.input_folders()))
    check_output_folder(out, force, inputs, RUN_KIND)
    start = load_checkpoint(weights) if weights is not None else None
    teacher_network = load_checkpoint(teacher, "--teacher") if teacher is not None else None
    student_size = start.size_wh if start is not None else CROP_SIZE_WH
    if teacher_network is not None and teacher_network.size_wh != student_size:
        raise ValueError(f"{teacher}: its crop network looks at {_size(teacher_network.size_wh)} crops, the one "
                         f"trained here at {_size(student_size)} - give a teacher of the same crop size")
    if start is None and settings.epochs == 0:
        raise ValueError("--epochs 0 trains no new crop network, only on a trained one's second looks or its "
                         "preclassifier: give the one to start from with --weights (a poles-robot.pt)")
    began = time.perf_counter()
    train, valid = (crop_sets(datasets, split, settings.seed + offset, progress)
                    for split, offset in (("train", 0), ("valid", 1000)))
    for name, crops in (("train", train), ("valid", valid)):
        if not (crops.classes != NO_POLE).any():
            raise ValueError(f"{', '.join(map(str, data))}: no labelled pole in the {name} split - the crop network "
                             f"needs poles to learn from in train and valid (`poles split` makes both)")
    with output_folder(out, force, inputs, RUN_KIND) as folder:
        network, history = train_crop_network(train, valid, settings, start, teacher=teacher_network) \
            if settings.epochs else (start, [])
        if history and max(h.pole_recall for h in history) == 0:
            raise ValueError(f"{', '.join(map(str, data))}: after {len(history)} epoch(s) the crop network finds none "
                             f"of the {int((valid.classes != NO_POLE).sum())} pole crops of the valid frames, so no "
                             f"model was written - train on more frames ({sum(len(d.split('train')) for d in datasets)}"
                             " train frames here; the shipped model learnt from 7,000) or for more --epochs")
        difference = export_crop_network(network, folder / MODEL, valid.crops[:256], EXPORT_CONF)
        last_stage, mined = history, 0
        left = None if settings.minutes is None else settings.minutes - sum(h.seconds for h in history) / 60
        if settings.second_look_epochs and (left is None or left > 0):
            network, looks, mined = train_on_second_looks(network, folder / MODEL, datasets, train, valid,
                                                          replace(settings, minutes=left), progress,
                                                          teacher_network)
            last_stage = [replace(h, epoch=len(history) + h.epoch) for h in looks]
            history = history + last_stage
            difference = export_crop_network(network, folder / MODEL, valid.crops[:256], EXPORT_CONF)
        save_checkpoint(network, folder / CHECKPOINT, history, settings)
        preclassifier = add_preclassifier(folder / MODEL, network, datasets, valid, settings, progress) \
            if settings.preclassifier_epochs else None
        threshold, f1 = valid_threshold(folder / MODEL, opened, progress)
        training = {"minutes": round((time.perf_counter() - began) / 60, 1), "hardware": machine(),
                    "epochs": len(history), "frames": sum(len(dataset.split("train")) for dataset in datasets)}
        add_metadata(folder / MODEL, operating_conf=threshold, training=training)
        if history:  # a run that trained only a preclassifier has no epochs of the crop network to draw
            plot_crop_history(history, folder / "training_curves.png")
        best = max(last_stage, key=lambda h: h.score) if last_stage else None
        summary = RobotTraining(tuple(data), len(train), len(valid), int((train.classes != NO_POLE).sum()), mined, best,
                                len(history), round(sum(h.seconds for h in history) / 60, 2), float(difference),
                                float(threshold), float(f1), settings, preclassifier, weights, Path(out) / MODEL,
                                teacher)
        epochs = [asdict(h) for h in history]
        write_record(folder / "history.json", "robot training", {**summary.to_json(), "history": epochs})
    return summary


def _size(size_wh: tuple[int, int]) -> str:
    return f"{size_wh[0]}x{size_wh[1]}"


def add_preclassifier(model: Path, network: PoleCropNet, datasets: list[Dataset], valid: CropSet,
                      settings: CropTrainSettings, progress: bool = True) -> PreclassifierResult:
    """Train the preclassifier on the crop network's training windows, cut at its own size, choose its threshold on
    the valid windows against the crop network's answers there (``valid``: the same windows at the network's size),
    and store it in the network's model file."""
    small_train, small_valid = (crop_sets(datasets, split, settings.seed + offset, progress, PRECLASSIFIER_SIZE_WH)
                                for split, offset in (("train", 0), ("valid", 1000)))
    preclassifier, result = train_preclassifier(
        small_train, small_valid, valid, network, replace(settings, epochs=settings.preclassifier_epochs, minutes=None))
    add_metadata(model, **{PRECLASSIFIER_KEY: preclassifier_entry(
        preclassifier_onnx(preclassifier, small_valid.crops[:256]), result.threshold, result.kept_poles,
        result.rejected_clutter)})
    return result


def train_on_second_looks(network: PoleCropNet, model: Path, datasets: list[Dataset], train: CropSet, valid: CropSet,
                          settings: CropTrainSettings, progress: bool = True,
                          teacher: PoleCropNet | None = None) -> tuple[PoleCropNet, list[EpochResult], int]:
    """The network (exported at ``model``) trained on for ``settings.second_look_epochs`` with the second-look crops
    its first look finds in the train and valid frames added (learning ``teacher``'s class scores too, where there
    is one); returns the network, those epochs' figures and the number of second-look train crops."""
    detector = CropDetector(model, threads=settings.threads)
    train_looks, valid_looks = (second_look_crops(detector, datasets, split, progress) for split in ("train", "valid"))
    print(f"second looks: {len(train_looks)} train crops ({int((train_looks.classes != NO_POLE).sum())} poles), "
          f"{len(valid_looks)} valid; {settings.second_look_epochs} epochs more", flush=True)
    more = replace(settings, epochs=settings.second_look_epochs,
                   learning_rate=settings.learning_rate * SECOND_LOOK_LEARNING_RATE_SHARE)
    network, history = train_crop_network(CropSet.concatenate([train] + [train_looks] * SECOND_LOOK_REPEAT),
                                          CropSet.concatenate([valid, valid_looks]), more, network.train(),
                                          teacher=teacher)
    return network, history, len(train_looks)
