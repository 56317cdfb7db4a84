"""CPU training of YOLOv8 segmentation models with Ultralytics, offline, on every core.

Ultralytics on a CPU uses ``cpu_count - 1`` torch threads (one thread on a two-core laptop) and no data-loader
workers. ``train_model`` keeps Ultralytics' trainer and only lifts those two limits (see ``benchmarks/bench_train.py``
for what that buys), caches images in RAM when they fit, and never downloads: models are built from their YAML or
loaded from a local checkpoint, AMP checks and plots (which fetch a font) are off.
"""
from __future__ import annotations

import difflib
import math
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field
from functools import partial
from pathlib import Path

import cv2
import numpy as np
import torch
from ultralytics import YOLO
from ultralytics.cfg import check_cfg, smart_value
from ultralytics.models.yolo.segment import SegmentationTrainer
from ultralytics.utils import DEFAULT_CFG, DEFAULT_CFG_DICT, torch_utils

from detector.outputs import check_placement
from detector.console import bars_as_log_lines
from detector.training import defaults
from detector.training.cpu_threads import ThreadTuner
from detector.datasets.intake import open_dataset, training_view
from detector.model_files import read_checkpoint
from detector.training.curves import best_epoch, plot_training_curves, read_results
from detector.training.devices import check_device
from detector.training.distillation import check_teacher, shared_stride_distillation
from detector.training.summary import TrainingSummary
from naoslam.cores import usable_cores

#: Ultralytics' segmentation models that can be built from their YAML without a download.
ULTRALYTICS_MODELS = ("yolov8n-seg", "yolov8s-seg", "yolov8m-seg")
ARCHITECTURES_DIR = Path(__file__).resolve().parent / "architectures"
#: This package's own architectures, small enough for the Nao's CPU: one YAML each in ``architectures/``.
ROBOT_MODELS = tuple(sorted(path.stem for path in ARCHITECTURES_DIR.glob("*.yaml")))
#: Every architecture ``poles train --model`` builds.
MODELS = ULTRALYTICS_MODELS + ROBOT_MODELS


def architecture_yaml(model: str) -> str:
    """The YAML that builds ``model``: Ultralytics' own by name, or this package's file for a robot architecture."""
    return str(ARCHITECTURES_DIR / f"{model}.yaml") if model in ROBOT_MODELS else f"{model}.yaml"
#: Ultralytics training arguments that ``poles train`` sets itself (its own flag, or fixed for an offline CPU run).
MANAGED_ARGUMENTS = {"data": "--data", "project": "--out", "name": "--out", "exist_ok": "--out", "model": "--model",
                     "epochs": "--epochs", "time": "--time", "imgsz": "--imgsz", "batch": "--batch",
                     "patience": "--patience", "seed": "--seed", "workers": "--workers", "cache": "--no-cache",
                     "device": "--device", "resume": "--resume", "save_dir": "--out", "distill_model": "--teacher",
                     "amp": "", "plots": "",
                     "deterministic": "", "mode": "", "task": "", "cfg": ""}


@dataclass(frozen=True)
class TrainSettings:
    """What ``poles train`` passes to Ultralytics; the defaults are ``detector.training.defaults``."""

    model: str = defaults.MODEL
    epochs: int = defaults.EPOCHS
    imgsz: int = defaults.IMGSZ
    batch: int = defaults.BATCH
    patience: int = defaults.PATIENCE
    seed: int = defaults.SEED
    threads: int | None = None
    workers: int = defaults.WORKERS
    cache: bool = True
    time_hours: float | None = None
    #: With ``time_hours``: at most this many epochs, the learning-rate schedule spanning the epochs that fit in the
    #: time or these, whichever are fewer (Ultralytics alone stretches the epochs to fill the time).
    max_epochs: int | None = None
    #: Ultralytics' device string: "cpu" (default), "0", "0,1" (DDP across GPUs) or "mps".
    device: str = defaults.DEVICE
    #: Let ``ThreadTuner`` pick the thread count by timing batches (``--threads auto``); off by default (docs/training.md).
    adaptive_threads: bool = False
    #: A larger model whose features the network learns (``poles train --teacher``); see ``distillation``.
    teacher: Path | None = None
    #: Further Ultralytics training arguments (``--set lr0=0.0002``), already typed; see ``parse_hyperparameters``.
    hyperparameters: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.model not in MODELS:
            raise ValueError(f"--model {self.model!r} is not one of {', '.join(MODELS)}")
        for name in ("epochs", "imgsz", "batch"):
            if getattr(self, name) < 1:
                raise ValueError(f"--{name} must be at least 1 (got {getattr(self, name)})")
        if self.time_hours is not None and not (math.isfinite(self.time_hours) and self.time_hours > 0):
            raise ValueError(f"--time {self.time_hours} must be a positive number of hours")
        if self.max_epochs is not None and self.max_epochs < 1:
            raise ValueError(f"--epochs {self.max_epochs} must be at least 1")
        if self.imgsz % 32:
            raise ValueError(f"--imgsz {self.imgsz} is not a multiple of the model stride 32 (try {self.imgsz // 32 * 32 or 32})")


def parse_hyperparameters(pairs: list[str]) -> dict:
    """``KEY=VALUE`` strings as Ultralytics training arguments, typed and checked as Ultralytics' ``yolo`` CLI does.

    Refuses a key Ultralytics does not know (naming the closest ones) and a key ``poles train`` sets itself (naming
    its flag), so a typo cannot be silently ignored and a flag cannot be silently overridden.
    """
    hyperparameters = {}
    for pair in pairs:
        key, equals, text = pair.partition("=")
        key = key.strip()
        if not equals or not key:
            raise ValueError(f"--set {pair!r}: write KEY=VALUE, e.g. --set lr0=0.0002")
        if key in MANAGED_ARGUMENTS:
            flag = MANAGED_ARGUMENTS[key]
            raise ValueError(f"--set {key}: poles train sets {key} itself" + (f" - use {flag}" if flag else ""))
        if key not in DEFAULT_CFG_DICT:
            close = difflib.get_close_matches(key, DEFAULT_CFG_DICT, n=3)
            raise ValueError(f"--set {key}: not an Ultralytics training argument"
                             + (f" - did you mean {', '.join(close)}?" if close else ""))
        value = smart_value(text.strip())
        try:
            check_cfg({key: value})
        except (TypeError, ValueError) as exc:
            raise ValueError(f"--set {pair}: {str(exc).splitlines()[0]}") from None
        hyperparameters[key] = value
    return hyperparameters


def use_all_cores(threads: int | None = None) -> int:
    """Make Ultralytics' ``select_device`` give torch ``threads`` (default: every core this process may use) instead
    of cpu_count - 1."""
    threads = threads or usable_cores()
    torch_utils.NUM_THREADS = threads
    torch_utils.torch.set_num_threads(threads)
    return threads


class CpuSegmentationTrainer(SegmentationTrainer):
    """Ultralytics' segmentation trainer, except that the data-loader worker count asked for is kept on a CPU, and
    that a time-capped run stops after ``max_epochs`` when those come first."""

    def __init__(self, cfg=DEFAULT_CFG, overrides: dict | None = None, _callbacks=None, max_epochs: int | None = None):
        workers = (overrides or {}).get("workers")
        super().__init__(cfg=cfg, overrides=overrides, _callbacks=_callbacks)
        if workers is not None:
            self.args.workers = workers
        self.max_epochs = max_epochs

    def _setup_scheduler(self) -> None:
        """Ultralytics' schedule, over at most ``max_epochs``: in time mode it re-estimates the epochs that fill the
        time after every epoch and calls this, then stops once the epoch count is reached. A resumed run's time is
        what is left of its budget, so the epochs that fill it come after those already trained."""
        if self.args.time and self.start_epoch > 0:
            self.epochs = self.args.epochs = self.start_epoch + self.epochs
        if self.max_epochs is not None:
            self.epochs = self.args.epochs = min(self.epochs, self.max_epochs)
        super()._setup_scheduler()


def train_model(data: Path, out: Path, settings: TrainSettings, weights: Path | None = None,
                resume: bool = False, progress: bool = True) -> Path:
    """Train (or resume) into the run folder ``out``; returns it. Writes ``training_curves.png`` beside results.csv.

    The dataset is checked as every command checks it (``intake.open_dataset``) and Ultralytics reads a view of it
    inside the run (``out/dataset``), so its caches never land in the input. A plain rerun replaces a run that did
    not finish; a finished run is kept (pick a new ``out``).
    """
    out = Path(out).resolve()
    check_device(settings.device)
    tuner = None
    if settings.device == "cpu":
        threads = use_all_cores(settings.threads)
        tuner = ThreadTuner(threads) if settings.adaptive_threads else None
    if resume:
        last = out / "weights" / "last.pt"
        data_yaml = _resumable_data(last)  # before Ultralytics sees the path: it would look for a missing file online
        left = {"time": settings.time_hours} if settings.time_hours else {}  # what is left of the run's budget
        _train(YOLO(str(last)), tuner, max_epochs=settings.max_epochs, resume=True, data=data_yaml,
               workers=settings.workers, **left)
    else:
        if weights and not Path(weights).is_file():
            raise FileNotFoundError(f"{weights}: no such checkpoint (nothing is downloaded: pass a local .pt)")
        if weights:
            read_checkpoint(Path(weights))  # a clear error for a file that is not a checkpoint
        if settings.teacher:
            check_teacher(Path(settings.teacher))
            print(f"distilling from {settings.teacher}")
        print(f"starting from {weights or f'{settings.model}.yaml (no pretrained weights)'}")
        dataset = open_dataset(data, progress=progress)
        check_placement(out, (*dataset.input_folders(), *([Path(weights)] if weights else [])))
        _clear_unfinished_run(out)
        with _removed_unless_resumable(out):
            data_yaml = training_view(dataset, out / "dataset")
            model = YOLO(str(weights) if weights else architecture_yaml(settings.model), task="segment")
            options = asdict(settings)
            for name in ("model", "threads", "adaptive_threads", "max_epochs"):
                options.pop(name)
            options["time"] = options.pop("time_hours")
            teacher = options.pop("teacher")
            if teacher:
                options["distill_model"] = str(teacher)
            options.update(options.pop("hyperparameters"))
            _train(model, tuner, max_epochs=settings.max_epochs, data=str(data_yaml), project=str(out.parent),
                   name=out.name, exist_ok=True, amp=False, plots=False, deterministic=True, **options)
    plot_training_curves(out / "results.csv", out / "training_curves.png")
    return out


def trained_minutes(run: Path) -> float:
    """Minutes a run has trained so far, over every call that trained it (Ultralytics' results.csv counts each
    call's time from that call's start)."""
    path = Path(run) / "results.csv"
    if not path.is_file():
        return 0.0
    times = read_results(path).get("time", [])
    ends = [t for t, after in zip(times, times[1:] + [-1.0]) if after < t]  # each call's last epoch
    return sum(ends) / 60


def _train(model: YOLO, tuner: ThreadTuner | None, max_epochs: int | None = None, **options) -> None:
    """``model.train(**options)`` with ``CpuSegmentationTrainer`` (at most ``max_epochs``), the thread tuner watching
    every batch when there is one, progress bars written as whole lines into a log, and a teacher distilled at the
    strides it shares with the network."""
    if tuner is not None:
        model.add_callback("on_train_batch_end", tuner)
    with bars_as_log_lines(), shared_stride_distillation():
        model.train(trainer=partial(CpuSegmentationTrainer, max_epochs=max_epochs), **options)


@contextmanager
def _removed_unless_resumable(out: Path) -> Iterator[None]:
    """Remove the run folder ``out`` when the block fails before Ultralytics saved a ``last.pt`` to resume from (a
    device that is not there, Ctrl-C in the first epoch): nothing is left behind that ``--resume`` cannot use."""
    try:
        yield
    except BaseException:
        if not (out / "weights" / "last.pt").is_file():
            shutil.rmtree(out, ignore_errors=True)
        raise


def _clear_unfinished_run(out: Path) -> None:
    """Remove what an unfinished run left in ``out``; refuse when ``out`` holds a finished run or other files."""
    if not out.exists():
        return
    if not out.is_dir():
        raise FileExistsError(f"--out {out} is a file: give a folder for the run")
    if not any(out.iterdir()):
        return
    last = out / "weights" / "last.pt"
    if last.is_file() and _finished(last):
        raise FileExistsError(f"{out} already holds a finished run - pick a new --out, or fine-tune it with "
                              f"--weights {out / 'weights' / 'best.pt'}")
    if not (out / "args.yaml").is_file() and not (out / "dataset").is_dir():
        raise FileExistsError(f"{out} holds files that are not a training run - pick a new --out")
    print(f"replacing the unfinished run in {out}" + (" (--resume would continue it from last.pt)" if last.is_file() else ""))
    shutil.rmtree(out)


def _finished(last: Path) -> bool:
    """True when the checkpoint is the final one of its run (Ultralytics marks it with epoch -1)."""
    try:
        return read_checkpoint(last).get("epoch", -1) < 0
    except Exception:  # an unreadable checkpoint belongs to an unfinished run
        return False


def _resumable_data(last: Path) -> str:
    """The dataset of an interrupted run, or an error saying why it cannot be resumed."""
    if not last.is_file():
        raise FileNotFoundError(f"{last}: nothing to resume - start the run without --resume")
    checkpoint = read_checkpoint(last)
    if checkpoint.get("epoch", -1) < 0:
        raise ValueError(f"{last}: this run finished all its epochs, nothing to resume - "
                         "fine-tune with --weights to train further")
    return checkpoint["train_args"]["data"]


def recalibrate_batchnorm(weights: Path, images: list[Path], imgsz: tuple[int, int], out: Path) -> Path:
    """Re-estimate a checkpoint's batch-norm running statistics on ``images`` (one pass, exact averages).

    After very short training the running statistics still sit near their initial values (Ultralytics' momentum
    is 0.03), so the network answers every frame alike; this is the "precise BN" fix. Writes a new checkpoint.
    """
    checkpoint = read_checkpoint(weights)
    model = (checkpoint.get("ema") or checkpoint["model"]).float()
    frames = [cv2.resize(cv2.imread(str(p)), imgsz[::-1])[:, :, ::-1] for p in images]
    batch = torch.from_numpy(np.stack(frames).transpose(0, 3, 1, 2).copy()).float() / 255
    for module in model.modules():
        if isinstance(module, torch.nn.BatchNorm2d):
            module.reset_running_stats()
            module.momentum = None
    model.train()
    with torch.no_grad():
        model(batch)
    model.eval()
    checkpoint.update(model=model.half(), ema=None)
    torch.save(checkpoint, str(out))
    return Path(out)


def summarise_run(run: Path, model: str, started_from: Path | None = None, minutes: float | None = None,
                  kept: str = "best") -> TrainingSummary:
    """The run's summary from its results.csv: its best validation epoch, and the weights it hands on (``kept``:
    ``best`` or ``last``)."""
    run = Path(run)
    best = best_epoch(run / "results.csv")
    return TrainingSummary(model, started_from, run / "weights" / f"{kept}.pt", run / "training_curves.png",
                           best.epochs, minutes, best)
