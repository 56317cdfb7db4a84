"""``poles export``: ONNX export, verification against PyTorch, optional INT8 copy, and a report."""
from __future__ import annotations

from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from rich.table import Table

from detector.console import make_console
from detector.datasets.intake import open_dataset
from detector.outputs import check_output_file
from detector.model_files import read_checkpoint, ultralytics_predict
from export.onnx_export import NAO_INPUT_HW, export_onnx, int8_path
from export.quantize import quantize_int8
from export.verify import FP32_TOLERANCE, INT8_TOLERANCE, Agreement, compare, frontend_predict, median_latency_ms
from detector.atomic import atomic_path
from detector.formats import write_record
from detector.records import JsonRecord
from naoslam.perception.pole_model import valid_confidence
from naoslam.shipped import DEFAULT_CONF

#: Frames used to verify an export, and images used to calibrate INT8.
VERIFY_FRAMES = 16
CALIBRATION_IMAGES = 64


class ExportMismatch(ValueError):
    """The exported model does not give the answers the checkpoint gives."""


@dataclass(frozen=True)
class ExportReport(JsonRecord):
    """What ``poles export`` wrote and how the files agree with the checkpoint (also ``MODEL.export.json``)."""

    weights: Path
    onnx: Path
    input_hw: tuple[int, int]
    dynamic: bool
    #: The input size the export was checked at (Ultralytics' own for a dynamic export).
    verified_at_hw: tuple[int, int]
    verify_frames: int
    conf: float
    fp32_vs_pytorch: Agreement
    fp32_problems: tuple[str, ...]
    #: Median milliseconds per frame through the front end, by file (``fp32``, ``int8``).
    latency_ms: dict[str, float]
    #: ``fp32`` or ``int8``: the faster file that agrees.
    recommended: str
    int8: Path | None = None
    calibration_images: int = 0
    int8_vs_fp32: Agreement | None = None
    int8_problems: tuple[str, ...] = ()

    @property
    def width(self) -> int:
        """The network's input width."""
        return self.input_hw[1]

    def comparisons(self) -> list[tuple[str, Agreement, tuple[str, ...]]]:
        """Each comparison made: its label, the agreement and its problems."""
        made = [("ONNX FP32 vs PyTorch", self.fp32_vs_pytorch, self.fp32_problems)]
        if self.int8_vs_fp32 is not None:
            made.append(("ONNX INT8 vs FP32", self.int8_vs_fp32, self.int8_problems))
        return made


@dataclass(frozen=True)
class ExportJob:
    weights: Path
    out: Path
    #: None: the checkpoint's training width, its height from the verification frames' shape (``input_size``).
    input_hw: tuple[int, int] | None = None
    data: Path | None = None
    int8: bool = False
    calib_data: Path | None = None
    reduce_range: bool = False
    conf: float = DEFAULT_CONF
    force: bool = False
    dynamic: bool = False

    def __post_init__(self) -> None:
        if self.out.suffix != ".onnx":
            raise ValueError(f"--out {self.out}: name the ONNX file to write, ending in .onnx, e.g. "
                             f"{self.out.with_name(self.out.name + '.onnx')}; nothing was written")
        if self.input_hw is not None and any(side < 16 or side % 16 for side in self.input_hw):
            raise ValueError(f"--imgsz {self.input_hw[0]} {self.input_hw[1]}: height and width must be positive "
                             "multiples of the model's stride, 32 for YOLOv8 (the Nao's frames: 480 640) or 16 for "
                             "robot-p4-seg (240 320, with --dynamic)")
        valid_confidence(self.conf)

    @property
    def int8_path(self) -> Path:
        return int8_path(self.out)

    @property
    def report_path(self) -> Path:
        return self.out.with_suffix(".export.json")


def dataset_images(data: Path, splits: tuple[str, ...], limit: int, flag: str) -> list[Path]:
    """Up to ``limit`` image paths from the given splits, spread evenly over them in file order; ``flag`` is the
    option that chose ``data``, named in the error when the splits hold no image."""
    samples = [s for s in open_dataset(data, progress=False).samples if s.split in splits and s.image]
    if not samples:
        raise ValueError(f"{data}: no images in the {'/'.join(splits)} split(s) - give {flag} a dataset that has "
                         "some; nothing was written")
    picks = np.linspace(0, len(samples) - 1, min(limit, len(samples))).round().astype(int)
    return [samples[i].image for i in sorted(set(picks))]


def training_dataset(weights: Path) -> Path:
    """The dataset folder a checkpoint was trained on (from its train_args), for when --data is not given."""
    data = (read_checkpoint(weights).get("train_args") or {}).get("data")
    if not data or not Path(data).exists():
        raise FileNotFoundError(f"{weights}: the dataset it was trained on ({data}) is not here - pass --data DATA")
    return Path(data).parent if Path(data).is_file() else Path(data)


def read_frames(paths: list[Path]) -> list[np.ndarray]:
    """The frames as BGR arrays; the first file that does not decode is named in the error."""
    frames = [cv2.imread(str(p)) for p in paths]
    bad = [str(p) for p, f in zip(paths, frames) if f is None]
    if bad:
        raise ValueError(f"{bad[0]}: cannot be decoded as an image - run `poles check` on the dataset")
    return frames


def input_size(checkpoint: dict, frame_hw: tuple[int, int]) -> tuple[int, int]:
    """The input (height, width) a checkpoint is exported at by default: the width it was trained at, the height
    in the frames' proportion, rounded up to a multiple of 32 (Ultralytics' predictor, which trained and validated it,
    rounds so). Roboflow's square frames give a square input; the Nao's 640x480 frames give 480x640 (256x320 for a
    320 px robot model)."""
    trained = (checkpoint.get("train_args") or {}).get("imgsz")
    width = int(trained if isinstance(trained, int) else max(trained or NAO_INPUT_HW))
    width = -(-width // 32) * 32
    return -(-round(width * frame_hw[0] / frame_hw[1]) // 32) * 32, width


def verification_size(input_hw: tuple[int, int], dynamic: bool) -> tuple[int, int]:
    """The input size the export is checked against PyTorch at: ``input_hw`` rounded up to 32, the multiple that
    Ultralytics' predictor (the reference) pads to. A size off that grid needs a dynamic export, which runs both."""
    rounded = (-(-input_hw[0] // 32) * 32, -(-input_hw[1] // 32) * 32)
    if rounded != tuple(input_hw) and not dynamic:
        raise ValueError(f"--imgsz {input_hw[0]} {input_hw[1]}: Ultralytics' predictor, which checks the export, "
                         f"runs only at multiples of 32 ({rounded[0]} {rounded[1]}) - add --dynamic, or export at "
                         f"{rounded[0]} {rounded[1]}")
    return rounded


def run_export(job: ExportJob) -> ExportReport:
    """Export, verify, optionally quantise; returns the report (also written to ``job.report_path``)."""
    checkpoint = read_checkpoint(job.weights)  # a clear error for a missing file or one that is not a checkpoint
    data = job.data or training_dataset(job.weights)
    inputs = tuple(path for path in (job.weights, data, job.calib_data) if path is not None)
    for output in (job.out, job.report_path) + ((job.int8_path,) if job.int8 else ()):
        check_output_file(output, job.force, inputs)
    frames = read_frames(dataset_images(data, ("valid", "test"), VERIFY_FRAMES, "--data"))
    input_hw = job.input_hw or input_size(checkpoint, frames[0].shape[:2])
    checked_hw = verification_size(input_hw, job.dynamic)
    calibration = dataset_images(job.calib_data or data, ("train",), CALIBRATION_IMAGES,
                                 "--calib-data" if job.calib_data else "--data (or --calib-data)") if job.int8 else []
    with ExitStack() as outputs:  # every file lands together, after the report is made, or none does
        fp32_path = outputs.enter_context(atomic_path(job.out))
        export_onnx(job.weights, fp32_path, input_hw, force=True, dynamic=job.dynamic)
        reference = ultralytics_predict(job.weights, frames, checked_hw, job.conf)
        fp32 = frontend_predict(fp32_path, frames, job.conf, checked_hw)
        agreement = compare(reference, fp32, job.conf, FP32_TOLERANCE.margin)
        fp32_problems = tuple(agreement.problems(FP32_TOLERANCE))
        if fp32_problems:
            raise ExportMismatch(f"{job.weights}: the ONNX export disagrees with PyTorch on {len(frames)} frames: "
                                 + "; ".join(fp32_problems) + " - nothing was written")
        models, int8 = {"fp32": fp32_path}, {}
        if job.int8:
            int8_path = outputs.enter_context(atomic_path(job.int8_path))
            quantize_int8(fp32_path, int8_path, calibration, reduce_range=job.reduce_range)
            against = compare(fp32, frontend_predict(int8_path, frames, job.conf, checked_hw), job.conf,
                              INT8_TOLERANCE.margin)
            int8 = {"int8": job.int8_path, "calibration_images": len(calibration), "int8_vs_fp32": against,
                    "int8_problems": tuple(against.problems(INT8_TOLERANCE))}
            models["int8"] = int8_path
        latency = median_latency_ms(models, frames[:8])
        report = ExportReport(job.weights, job.out, input_hw, job.dynamic, checked_hw, len(frames), job.conf,
                              agreement, fp32_problems, latency, _recommend(latency, int8.get("int8_problems")),
                              **int8)
        write_record(job.report_path, "export report", report.to_json())
    return report


def _recommend(latency: dict[str, float], int8_problems: tuple[str, ...] | None) -> str:
    """INT8 when it agrees with FP32 and saves a tenth of the time, else FP32."""
    if "int8" not in latency or int8_problems:
        return "fp32"
    return "int8" if latency["int8"] < 0.9 * latency["fp32"] else "fp32"


def verdict(agreement: Agreement, problems: tuple[str, ...]) -> str:
    """One comparison's verdict: its problems, that nothing was compared, or that the two agree."""
    if problems:
        return "; ".join(problems)
    if not agreement.reference and not agreement.candidate:
        return "nothing compared: no detection on any frame (give --data frames with poles, or a lower --conf)"
    return "agrees"


#: Rows of an agreement table: label and how to show one comparison's figure.
AGREEMENT_ROWS = {"detections (ref / new)": lambda a: f"{a.reference} / {a.candidate}",
                  "matched": lambda a: str(a.matched),
                  "confident unmatched": lambda a: str(a.unmatched_confident),
                  "class changes": lambda a: str(a.class_mismatches),
                  "box IoU min / mean": lambda a: f"{a.box_iou_min:.4f} / {a.box_iou_mean:.4f}",
                  "mask IoU min / mean": lambda a: f"{a.mask_iou_min:.4f} / {a.mask_iou_mean:.4f}",
                  "max score difference": lambda a: f"{a.score_diff_max:.4f}"}


def print_report(report: ExportReport) -> None:
    """The agreement and speed figures as a table, one column per comparison."""
    comparisons = report.comparisons()
    height, width = report.input_hw
    checked_height, checked_width = report.verified_at_hw
    checked = "" if (height, width) == (checked_height, checked_width) else \
        f", checked at {checked_width}x{checked_height} (Ultralytics' size)"
    table = Table(title=f"export at {width}x{height}{checked}: {report.verify_frames} frames, conf {report.conf}")
    table.add_column("")
    for label, _, _ in comparisons:
        table.add_column(label, justify="right")
    for name, cell in AGREEMENT_ROWS.items():
        table.add_row(name, *(cell(a) if a.reference or a.candidate else "-" for _, a, _ in comparisons))
    table.add_row("verdict", *(verdict(a, problems) for _, a, problems in comparisons))
    console = make_console()
    console.print(table)
    latency = ", ".join(f"{k} {v:.1f} ms" for k, v in report.latency_ms.items())
    console.print(f"front end per frame: {latency}; use {report.recommended.upper()}; wrote {report.onnx}"
                  + (f" and {report.int8}" if report.int8 else ""))
