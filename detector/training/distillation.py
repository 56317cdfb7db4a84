"""Knowledge distillation from a larger pole model into a network whose head has fewer pyramid levels.

Ultralytics' ``DistillationModel`` (training argument ``distill_model``) teaches the student the teacher's neck
features level by level, each place weighted by the teacher's class score there, and refuses two heads of different
depth. The robot networks see strides 8 and 16 (``robot-p4-seg``) where the accurate model sees 8, 16 and 32:
``SharedStrideDistillation`` distils the levels whose strides both heads have and leaves the rest to the usual loss.
"""
from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from torch import nn
from ultralytics.engine import trainer as ultralytics_trainer
from ultralytics.nn.distill_model import DistillationModel, FeatureHook
from ultralytics.nn.modules.head import Detect

from detector.model_files import read_checkpoint

#: The pyramid strides every network of this package has, so the levels a teacher and its student share.
SHARED_STRIDES = (8, 16)


class SharedStrideScoresHook(FeatureHook):
    """Stores the teacher head's class scores over the anchors of its first ``levels`` pyramid levels only, so that
    they line up with the neck features that are distilled."""

    def __init__(self, feat_dict: dict, idx: int, levels: int) -> None:
        super().__init__(feat_dict, idx)
        self.levels = levels

    def __call__(self, module: nn.Module, inputs: tuple, output) -> None:
        level_features = inputs[0]
        anchors = sum(feature.shape[-2] * feature.shape[-1] for feature in level_features[:self.levels])
        predictions = output[1] if isinstance(output, tuple) else output
        self.feat_dict[self.idx] = {"scores": predictions["scores"][..., :anchors]}


class SharedStrideDistillation(DistillationModel):
    """Ultralytics' distillation restricted to the pyramid levels of ``SHARED_STRIDES``."""

    @staticmethod
    def get_distill_layers(model: nn.Module) -> list[int]:
        """The layers feeding the head at the shared strides, then the head itself."""
        head = next((module for module in model.model if isinstance(module, Detect)), None)
        if head is None:
            raise ValueError("No Detect head found in model")
        strides = [int(stride) for stride in head.stride.tolist()]
        return [layer for layer, stride in zip(head.f, strides) if stride in SHARED_STRIDES] + [head.i]

    def _register_feature_hooks(self) -> None:
        """Ultralytics' hooks, with the teacher head's scores cut to the shared levels."""
        super()._register_feature_hooks()
        if self.teacher_model is None:  # a checkpoint's copy: the teacher is stripped before saving
            return
        head = self.teacher_model.model[self.teacher_feats_idx[-1]]
        self._clear_feature_hooks(head)
        levels = len(self.feats_idx) - 1
        hook = SharedStrideScoresHook(self._teacher_feats, idx=levels, levels=levels)
        self._teacher_hooks.append(head.register_forward_hook(hook))


def check_teacher(path: Path) -> None:
    """Refuse, in one line naming it, a teacher checkpoint that holds no YOLO detection or segmentation network."""
    checkpoint = read_checkpoint(path)
    network = checkpoint.get("ema") or checkpoint.get("model")
    if not any(isinstance(module, Detect) for module in getattr(network, "model", [])):
        raise ValueError(f"{path}: not a YOLO detection or segmentation model - pass a pole model as --teacher, "
                         "e.g. detector/weights/poles-yolov8n-seg.pt")


@contextmanager
def shared_stride_distillation() -> Iterator[None]:
    """Make Ultralytics' trainer build ``SharedStrideDistillation`` when ``distill_model`` is set."""
    original = ultralytics_trainer.DistillationModel
    ultralytics_trainer.DistillationModel = SharedStrideDistillation
    try:
        yield
    finally:
        ultralytics_trainer.DistillationModel = original
