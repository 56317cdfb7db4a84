"""How ``poles finetune`` trains on a few hundred real frames: the settings, and how the minutes are shared.

The defaults were chosen by the runs in docs/finetune.md (the rule that picked them was written there before the
deciding runs ended). Torch-free, so the command line builds its parser without loading a framework.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from pathlib import Path

from augment.config import THESIS_COPIES

#: Blend shares tried on the export's valid split: the fine-tune's share, 0 being the shipped model.
BLEND_SHARES = (0.0, 0.25, 0.5, 0.75, 1.0)
#: The share shipped unless the valid split shows another to be better frame by frame (docs/finetune.md).
DEFAULT_BLEND_SHARE = 0.5
#: The one-sided sign test's level for that showing: at least five frames better and none worse.
SIGN_TEST_LEVEL = 0.05


@dataclass(frozen=True)
class StartingModel:
    """A shipped model a team fine-tunes: its shipped name (``shipped`` or ``shipped-robot``), its ``network``
    (``yolo``: a YOLOv8-seg trained by Ultralytics at ``imgsz``, the first ``backbone_layers`` kept by default;
    ``crops``: the robot's two-stage crop network, trained by ``detector.crops``), its measured recipe defaults (the
    share of rendered frames, an epoch cap or None for as many as the minutes allow, AdamW's step; docs/finetune.md), whether
    an INT8 copy is exported beside the FP32 model (the accurate one's; at the Atom's instruction set FP32 is the
    faster), and the file name the fine-tune is delivered under."""

    shipped: str
    network: str
    architecture: str
    imgsz: int | None
    backbone_layers: int
    rehearsal_share: float
    epochs: int | None
    lr0: float
    int8: bool
    finetuned_name: str

    @property
    def weights(self) -> Path:
        """The shipped checkpoint a fine-tune starts from and is blended and compared with."""
        from detector.model_files import ROBOT_WEIGHTS, SHIPPED_WEIGHTS  # deferred: `poles --help` reads the recipe

        return ROBOT_WEIGHTS if self.network == "crops" else SHIPPED_WEIGHTS


#: The shipped models ``poles finetune --model`` starts from.
STARTING_MODELS = {"accurate": StartingModel("shipped", "yolo", "yolov8n-seg", 640, 10, rehearsal_share=0.5,
                                             epochs=None, lr0=0.0005, int8=True, finetuned_name="poles-finetuned.onnx"),
                   "robot": StartingModel("shipped-robot", "crops", "pole-crops", None, 0, rehearsal_share=0.75,
                                          epochs=30, lr0=0.0003, int8=False, finetuned_name="poles-robot-finetuned.onnx")}


@dataclass(frozen=True)
class FinetuneRecipe:
    """One fine-tune's settings. ``model``: the shipped model it starts from (``STARTING_MODELS``);
    ``rehearsal_share``: the share of the training frames that are rendered (``own_paint_share`` of them in the
    team's paint, the rest in the renderer's own, and ``far_share`` of them with far poles only; ``backdrop_share`` of
    them drawn over the frames in ``backgrounds``, a folder of the team's own frames without poles, when one is given);
    ``epochs``: at most this many training epochs within the minutes; ``freeze``: the first layers left as shipped;
    ``lr0``/``warmup_epochs``: AdamW's step and its ramp. ``rehearsal_share``, ``epochs``, ``freeze``, ``lr0`` and
    ``imgsz`` left None take the starting model's."""

    model: str = "accurate"
    minutes: float = 15.0
    epochs: int | None = None
    copies: int = THESIS_COPIES
    rehearsal_share: float | None = None
    far_share: float = 0.5
    own_paint_share: float = 0.5
    backgrounds: str | None = None
    #: The shipped models' own share of frames over real backdrops.
    backdrop_share: float = 0.75
    freeze: int | None = None
    lr0: float | None = None
    warmup_epochs: float = 1.0
    imgsz: int | None = None
    batch: int = 8
    seed: int = 0
    #: Frames in each rendered set the models are judged on.
    evaluation_frames: int = 100
    #: A folder of unlabelled frames (or a video) the ``teacher`` labels where it is sure, trained on beside the
    #: export (the robot model only: the accurate model teaches it).
    unlabelled: str | None = None
    teacher: str = "shipped"

    def __post_init__(self) -> None:
        if self.model not in STARTING_MODELS:
            raise ValueError(f"--model {self.model!r} is not one of {', '.join(STARTING_MODELS)}")
        if not (math.isfinite(self.minutes) and self.minutes > 0):
            raise ValueError(f"--minutes {self.minutes} must be a positive number")
        if self.rehearsal_share is not None and not 0.0 <= self.rehearsal_share < 1.0:
            raise ValueError(f"--rehearsal-share {self.rehearsal_share} must lie in 0..1 (1 would train on no "
                             "frame of yours)")
        for name in ("far_share", "own_paint_share", "backdrop_share"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"{name.replace('_', ' ')} {getattr(self, name)} must lie in 0..1")
        if self.epochs is not None and self.epochs < 1:
            raise ValueError(f"--epochs {self.epochs} must be at least 1")
        if self.copies < 0:
            raise ValueError(f"--copies {self.copies} must be 0 or more")
        if self.freeze is not None and self.freeze < 0:
            raise ValueError(f"--freeze {self.freeze} must be 0 or more")
        if self.unlabelled is not None and self.model != "robot":
            raise ValueError("--unlabelled teaches the robot model with the accurate one as its teacher - add "
                             "--model robot (the accurate model would only learn its own answers back)")
        if self.imgsz is not None and self.imgsz % 32:
            raise ValueError(f"--imgsz {self.imgsz} is not a multiple of the model stride 32 (try "
                             f"{self.imgsz // 32 * 32 or 32})")

    @property
    def start(self) -> StartingModel:
        return STARTING_MODELS[self.model]

    @property
    def training_size(self) -> int:
        """The training (and judging) image size: ``imgsz``, else the starting model's."""
        return self.imgsz or self.start.imgsz

    @property
    def rendered_share(self) -> float:
        """The share of the training frames that are rendered: ``rehearsal_share``, else the starting model's."""
        return self.start.rehearsal_share if self.rehearsal_share is None else self.rehearsal_share

    @property
    def epoch_cap(self) -> int | None:
        """At most this many epochs within the minutes: ``epochs``, else the starting model's (None: no cap)."""
        return self.start.epochs if self.epochs is None else self.epochs

    @property
    def learning_rate(self) -> float:
        """AdamW's step: ``lr0``, else the starting model's."""
        return self.start.lr0 if self.lr0 is None else self.lr0

    @property
    def frozen_layers(self) -> int:
        """Layers kept as shipped: ``freeze``, else the starting model's backbone."""
        return self.start.backbone_layers if self.freeze is None else self.freeze

    def settings(self) -> dict:
        """Every field, and the values the ones left None resolve to for the starting model: what a run records."""
        return {**asdict(self), "rendered_share": self.rendered_share, "epoch_cap": self.epoch_cap,
                "frozen_layers": self.frozen_layers, "training_size": self.training_size,
                "learning_rate": self.learning_rate}

    def rehearsal_frames(self, real_training_frames: int) -> int:
        """Rendered frames to mix with ``real_training_frames`` (the augmented export) to reach ``rendered_share``."""
        return math.ceil(real_training_frames * self.rendered_share / (1.0 - self.rendered_share))

    def hyperparameters(self) -> dict:
        """The Ultralytics training arguments this recipe sets beyond ``TrainSettings``' own."""
        return {"optimizer": "AdamW", "lr0": self.learning_rate, "warmup_epochs": self.warmup_epochs, "freeze": self.frozen_layers}
