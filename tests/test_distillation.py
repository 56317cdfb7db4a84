"""`poles train --teacher`: a robot network learns the accurate model's features at the strides both heads have."""
from __future__ import annotations

import math

import pytest
import torch
from ultralytics.cfg import get_cfg
from ultralytics.nn.tasks import SegmentationModel, load_checkpoint

from detector.cli import main
from detector.model_files import SHIPPED_WEIGHTS, read_checkpoint
from detector.training.curves import read_results
from detector.training.distillation import SharedStrideDistillation
from detector.training.train import architecture_yaml, parse_hyperparameters


def _robot_student(imgsz: int) -> SegmentationModel:
    student = SegmentationModel(architecture_yaml("robot-p4-seg"), nc=6, verbose=False)
    student.args = get_cfg(overrides={"imgsz": imgsz})
    return student


def test_the_shared_levels_are_the_stride_8_and_16_inputs_of_each_head():
    """robot-p4-seg's head reads layers 10 and 13 (strides 8, 16); YOLOv8n-seg's reads 15, 18 and 21 (8, 16, 32)."""
    teacher = load_checkpoint(SHIPPED_WEIGHTS)[0]
    assert SharedStrideDistillation.get_distill_layers(_robot_student(64)) == [10, 13, 14]
    assert SharedStrideDistillation.get_distill_layers(teacher) == [15, 18, 22]


def test_the_teacher_scores_weigh_only_the_anchors_of_the_shared_levels():
    """At 64x96 the shared levels hold 8x12 + 4x6 = 120 anchors of the teacher's 126; the projectors map the
    student's 32 and 64 channels onto the teacher's 64 and 128, and the distillation loss is finite and positive."""
    model = SharedStrideDistillation(SHIPPED_WEIGHTS, _robot_student(64))
    model.teacher_model(torch.rand(2, 3, 64, 96))
    scores = model._teacher_feats[2]["scores"]
    assert scores.shape == (2, 6, 8 * 12 + 4 * 6)
    neck = [model._teacher_feats[level] for level in range(2)]
    assert [feature.shape[1:] for feature in neck] == [(64, 8, 12), (128, 4, 6)]
    assert [projector[0].in_channels for projector in model.projector] == [32, 64]
    model.student_model(torch.rand(2, 3, 64, 96))
    levels = [model.projector[level](model._student_feats[level]) for level in range(2)]
    weights = tuple(part.sigmoid().max(dim=1, keepdim=True).values
                    for part in torch.split(scores, [8 * 12, 4 * 6], dim=-1))
    losses = [model.loss_sl2(levels[level], neck[level], level, weights).item() for level in range(2)]
    assert all(math.isfinite(loss) and loss > 0 for loss in losses)


def test_a_distilled_robot_run_trains_and_saves_the_student_alone(synth_dataset, tmp_path):
    run = tmp_path / "run"
    assert main(["train", "--data", str(synth_dataset), "--out", str(run), "--model", "robot-p4-seg", "--weights",
                 "scratch", "--teacher", str(SHIPPED_WEIGHTS), "--epochs", "1", "--imgsz", "64", "--batch", "8"]) == 0
    distillation_loss = read_results(run / "results.csv")["train/dis_loss"]
    assert len(distillation_loss) == 1 and distillation_loss[0] > 0
    saved = read_checkpoint(run / "weights" / "best.pt")["model"]
    assert type(saved) is SegmentationModel and saved.model[-1].stride.tolist() == [8.0, 16.0]


@pytest.mark.parametrize("teacher, message", [("nowhere.pt", "nowhere.pt: no such checkpoint"),
                                              ("linear.pt", "linear.pt: not a YOLO detection or segmentation model")])
def test_a_teacher_that_is_not_a_pole_model_is_refused_in_one_line(teacher, message, synth_dataset, tmp_path, capsys):
    torch.save({"model": torch.nn.Linear(2, 2)}, tmp_path / "linear.pt")
    assert main(["train", "--data", str(synth_dataset), "--out", str(tmp_path / "run"), "--model", "robot-p4-seg",
                 "--teacher", str(tmp_path / teacher), "--imgsz", "64"]) == 2
    error = capsys.readouterr().err
    assert message in error and "Traceback" not in error
    assert not (tmp_path / "run").exists()


def test_the_teacher_is_set_by_its_flag_not_by_set():
    with pytest.raises(ValueError, match="use --teacher"):
        parse_hyperparameters(["distill_model=big.pt"])
