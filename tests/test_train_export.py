"""Training on the CPU, ONNX export with metadata, verification against PyTorch, INT8 quantisation."""
from __future__ import annotations

import json
import os
import shutil
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import onnx
import pytest

from detector.cli import main
from detector.training.train import TrainSettings, summarise_run, train_model
from detector.training.curves import read_results
from detector.model_files import read_checkpoint, read_info
from export.onnx_export import export_onnx
from export.quantize import decode_head_nodes
from export.run import ExportJob, ExportMismatch, ExportReport, run_export
from naoslam.perception.yolo import LandmarkDetector
from naoslam.landmarks import CLASSES


def test_training_writes_run_curves_and_best_epoch(tiny_run):
    assert (tiny_run / "weights" / "best.pt").is_file() and (tiny_run / "weights" / "last.pt").is_file()
    assert read_results(tiny_run / "results.csv")["epoch"] == [1.0]
    curves = cv2.imread(str(tiny_run / "training_curves.png"))
    assert curves is not None and curves.shape[1] > 1000
    summary = summarise_run(tiny_run, "yolov8n-seg")
    assert summary.best.epoch == 1 and 0.0 <= summary.best.mask_map50 <= 1.0
    assert summary.weights == tiny_run / "weights" / "best.pt" and summary.weights.is_file()


def test_training_uses_every_core_it_may_run_on(tiny_run):
    import torch

    assert torch.get_num_threads() == len(os.sched_getaffinity(0))


def test_training_refuses_an_existing_run_and_a_finished_resume(tiny_run, synth_dataset):
    settings = TrainSettings(model="yolov8n-seg", epochs=1, imgsz=64)
    with pytest.raises(FileExistsError, match="already holds a finished run"):
        train_model(synth_dataset, tiny_run, settings)
    with pytest.raises(ValueError, match="finished all its epochs"):
        train_model(synth_dataset, tiny_run, settings, resume=True)


@pytest.mark.parametrize("kwargs, message", [({"model": "yolov9-seg"}, "is not one of"),
                                             ({"imgsz": 100}, "multiple of the model stride"),
                                             ({"epochs": 0}, "at least 1"),
                                             ({"time_hours": float("nan")}, "positive number of hours")])
def test_train_settings_refuse_bad_values(kwargs, message):
    with pytest.raises(ValueError, match=message):
        TrainSettings(**kwargs)


def test_train_command_names_a_missing_dataset(tmp_path, capsys):
    assert main(["train", "--data", str(tmp_path / "nowhere"), "--out", str(tmp_path / "run")]) == 2
    error = capsys.readouterr().err
    assert "nowhere: error: no such file or folder" in error and "Traceback" not in error
    assert not (tmp_path / "run").exists()


def test_training_never_writes_into_the_dataset_and_a_rerun_replaces_a_failed_run(synth_dataset, tmp_path):
    before = {p: p.stat().st_mtime_ns for p in synth_dataset.rglob("*")}
    run = tmp_path / "run"
    (run / "weights").mkdir(parents=True)
    (run / "args.yaml").write_text("left by a run that crashed\n")
    train_model(synth_dataset, run, TrainSettings(model="yolov8n-seg", epochs=1, imgsz=64, batch=8))
    assert (run / "weights" / "best.pt").is_file() and list((run / "dataset").rglob("*.cache"))
    assert {p: p.stat().st_mtime_ns for p in synth_dataset.rglob("*")} == before


def test_export_carries_metadata(tiny_onnx):
    info = read_info(tiny_onnx)
    assert info.classes == CLASSES and info.input_hw == (96, 128) and info.stride == 32
    assert info.model.startswith("yolov8")
    shapes = [[d.dim_value for d in o.type.tensor_type.shape.dim] for o in onnx.load(str(tiny_onnx)).graph.output]
    assert shapes[0][:2] == [1, 4 + len(CLASSES) + 32] and shapes[1][:2] == [1, 32]


def test_export_never_overwrites_without_force(tiny_weights, tiny_onnx):
    with pytest.raises(FileExistsError, match="--force"):
        export_onnx(tiny_weights, tiny_onnx, (96, 128))


def test_decode_head_stays_float(tiny_onnx):
    excluded = decode_head_nodes(onnx.load(str(tiny_onnx)))
    assert any("/dfl/" in name for name in excluded)
    assert any("Concat" in name for name in excluded)
    assert not any("/proto/" in name or "cv2.0.0/" in name for name in excluded)
    assert all(name.startswith("/model.22/") for name in excluded)


def test_run_export_verifies_quantizes_and_reports(tiny_weights, synth_dataset, tmp_path):
    job = ExportJob(tiny_weights, tmp_path / "m.onnx", (96, 128), synth_dataset, int8=True, conf=0.001, dynamic=True)
    report = run_export(job)
    for model in (job.out, job.int8_path):  # --dynamic: both run on a band of any height
        detector = LandmarkDetector(model)
        assert detector.any_input_size and detector.input_hw == (96, 128)
        outputs = detector.forward(detector.prepare(np.zeros((40, 128, 3), np.uint8), (64, 128))[0])
        assert outputs[1].shape[2:] == (16, 32)
    assert report.fp32_problems == ()
    fp32 = report.fp32_vs_pytorch
    assert fp32.matched == fp32.reference > 0 and fp32.box_iou_min > 0.99
    assert read_info(job.int8_path).extra["precision"] == "int8"
    assert report.int8_vs_fp32.matched > 0
    assert set(report.latency_ms) == {"fp32", "int8"} and report.recommended in ("fp32", "int8")
    assert ExportReport.from_json(json.loads(job.report_path.read_text())) == report


def test_run_export_fails_and_writes_nothing_when_onnx_disagrees(tiny_weights, synth_dataset, tmp_path,
                                                                 monkeypatch):
    import export.run

    def shifted_boxes(model, frames, conf, input_hw):
        return [[replace(d, box=tuple(v + 4.0 for v in d.box)) for d in found] for found in
                export.run.ultralytics_predict(tiny_weights, frames, (96, 128), conf)]

    monkeypatch.setattr(export.run, "frontend_predict", shifted_boxes)
    job = ExportJob(tiny_weights, tmp_path / "m.onnx", (96, 128), synth_dataset, conf=0.001)
    with pytest.raises(ExportMismatch, match="box IoU down to"):
        run_export(job)
    assert list(tmp_path.iterdir()) == []


def test_run_export_writes_nothing_when_int8_cannot_be_made(tiny_weights, dataset_copy, tmp_path, monkeypatch):
    """The FP32 file used to land before INT8 was tried: a failed --int8 left a model without its report."""
    import export.run

    out = tmp_path / "out"
    no_train = dataset_copy.parent / "no-train"
    shutil.copytree(dataset_copy, no_train)
    for label in (no_train / "train").rglob("*.*"):
        label.unlink()
    job = ExportJob(tiny_weights, out / "m.onnx", (96, 128), dataset_copy, int8=True, calib_data=no_train, conf=0.001)
    with pytest.raises(ValueError, match="give --calib-data a dataset that has some; nothing was written"):
        run_export(job)
    assert not out.exists()

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(export.run, "quantize_int8", interrupted)
    with pytest.raises(KeyboardInterrupt):
        run_export(replace(job, calib_data=None))
    assert list(out.iterdir()) == []


def test_export_refuses_an_out_that_is_not_an_onnx_file(tiny_run, synth_dataset, tmp_path, capsys):
    """`--out run/export` once wrote an ONNX file named `export` that `poles evaluate` then refused to read."""
    argv = ["export", "--weights", str(tiny_run), "--data", str(synth_dataset), "--out", str(tmp_path / "export")]
    assert main(argv) == 2
    error = capsys.readouterr().err
    assert f"name the ONNX file to write, ending in .onnx, e.g. {tmp_path / 'export.onnx'}" in error
    assert "Traceback" not in error and list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("where, refusal", [("the checkpoint", "ending in .onnx"),
                                            ("inside the dataset", "overlaps the input")])
def test_export_never_writes_over_its_inputs_even_with_force(where, refusal, tiny_weights, dataset_copy, tmp_path,
                                                             capsys):
    weights = tmp_path / "best.pt"
    shutil.copyfile(tiny_weights, weights)
    out = weights if where == "the checkpoint" else dataset_copy / "model.onnx"
    before = weights.read_bytes()
    argv = ["export", "--weights", str(weights), "--data", str(dataset_copy), "--out", str(out), "--force"]
    assert main(argv) == 2
    assert refusal in capsys.readouterr().err
    assert weights.read_bytes() == before and not (dataset_copy / "model.onnx").exists()


@pytest.mark.parametrize("saved_an_epoch", [False, True])
def test_a_run_that_fails_leaves_only_what_resume_can_use(saved_an_epoch, synth_dataset, tmp_path, monkeypatch):
    """A device that is not there (`--device 0` without a GPU) used to leave RUN/dataset behind."""
    import detector.training.train as training

    def fail(model, tuner, **options):
        if saved_an_epoch:
            (tmp_path / "run" / "weights").mkdir(parents=True)
            (tmp_path / "run" / "weights" / "last.pt").write_bytes(b"epoch 1")
        raise RuntimeError("Invalid CUDA 'device=0' requested")

    monkeypatch.setattr(training, "_train", fail)
    with pytest.raises(RuntimeError, match="device=0"):
        train_model(synth_dataset, tmp_path / "run", TrainSettings(model="yolov8n-seg", epochs=1, imgsz=64))
    assert (tmp_path / "run").exists() == saved_an_epoch


def test_a_time_capped_run_stops_after_max_epochs_when_they_come_first(synth_dataset, tmp_path):
    settings = TrainSettings(model="yolov8n-seg", epochs=1000, imgsz=64, batch=8, time_hours=1.0, max_epochs=2)
    train_model(synth_dataset, tmp_path / "run", settings)
    results = read_results(tmp_path / "run" / "results.csv")
    assert results["epoch"] == [1.0, 2.0]
    assert read_checkpoint(tmp_path / "run" / "weights" / "last.pt")["epoch"] == -1  # finished, not cut off


def test_an_interrupted_run_resumes_where_it_stopped(synth_dataset, tmp_path, monkeypatch):
    import detector.training.train as training

    original = training.CpuSegmentationTrainer.__init__

    def interrupt_after_first_epoch(self, *args, **kwargs):
        original(self, *args, **kwargs)

        def stop(trainer):
            if trainer.epoch == 0:
                raise KeyboardInterrupt

        self.add_callback("on_fit_epoch_end", stop)

    settings = TrainSettings(model="yolov8n-seg", epochs=2, imgsz=64, batch=8)
    with monkeypatch.context() as patch:
        patch.setattr(training.CpuSegmentationTrainer, "__init__", interrupt_after_first_epoch)
        with pytest.raises(KeyboardInterrupt):
            train_model(synth_dataset, tmp_path / "run", settings)
    assert read_results(tmp_path / "run" / "results.csv")["epoch"] == [1.0]
    train_model(synth_dataset, tmp_path / "run", settings, resume=True)
    assert read_results(tmp_path / "run" / "results.csv")["epoch"] == [1.0, 2.0]


@pytest.mark.parametrize("trained, frame_hw, expected", [(640, (480, 640), (480, 640)), (640, (640, 640), (640, 640)),
                                                         (320, (480, 640), (256, 320)), ([96, 128], (240, 320), (96, 128))])
def test_export_takes_the_training_width_and_the_frames_proportion_by_default(trained, frame_hw, expected):
    """Roboflow's square frames export square, the Nao's 4:3 frames at 4:3, each at the width the model learnt."""
    from export.run import input_size

    assert input_size({"train_args": {"imgsz": trained}}, frame_hw) == expected


def test_an_export_off_ultralytics_grid_is_checked_at_it_and_must_be_dynamic():
    """Ultralytics' predictor, the reference, pads to multiples of 32: a 240x320 export is checked at 256x320, which
    only a dynamic graph can run."""
    from export.run import verification_size

    assert verification_size((240, 320), dynamic=True) == (256, 320)
    assert verification_size((480, 640), dynamic=False) == (480, 640)
    with pytest.raises(ValueError, match="add --dynamic, or export at 256 320"):
        verification_size((240, 320), dynamic=False)


def test_an_export_whose_frames_show_no_detection_says_nothing_was_compared(capsys):
    from export.run import print_report
    from export.verify import compare

    empty = compare([[]] * 4, [[]] * 4, conf=0.25)
    print_report(ExportReport(Path("m.pt"), Path("m.onnx"), (480, 640), False, (480, 640), 4, 0.25, empty, (),
                              {"fp32": 40.0}, "fp32"))
    printed = capsys.readouterr().out
    assert "nothing compared" in printed and "agrees" not in printed
