"""How the crop network is trained: one frozen settings object, torch-free, so ``poles train-robot`` builds its
help from it without loading a framework."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class CropTrainSettings:
    """How the crop network is trained."""

    epochs: int = 40
    batch: int = 256
    learning_rate: float = 3e-3
    weight_decay: float = 1e-4
    seed: int = 0
    threads: int = 2
    #: Stop after this many minutes of training even if epochs are left (None: run every epoch).
    minutes: float | None = None
    #: How far each crop's white balance, contrast and saturation are moved while training (``train.augment``).
    colour_jitter: float = 0.15
    #: Which epoch's weights are kept: ``best`` on the valid crops, or ``last`` (a valid split of a frame or two
    #: scores every epoch alike, and ``best`` would then keep the first).
    keep: str = "best"
    #: Epochs trained on after the first ``epochs``, with the second-look crops the network's own first look finds
    #: added (``detector.crops.second_look``); 0: none.
    second_look_epochs: int = 0
    #: Epochs of the preclassifier (``detector.crops.preclassifier``) trained on the same crops after the crop
    #: network, and stored in its model file; 0: none (the crop network then looks at every window).
    preclassifier_epochs: int = 10

    def __post_init__(self) -> None:
        if self.epochs < 0 or self.batch < 1 or self.threads < 1:
            raise ValueError(f"epochs {self.epochs}, batch {self.batch}, threads {self.threads}: give 0 or more epochs, "
                             "1 or more of the rest")
        if self.epochs == 0 and self.second_look_epochs == 0 and self.preclassifier_epochs == 0:
            raise ValueError("0 epochs, 0 second-look epochs and 0 preclassifier epochs train nothing: give epochs "
                             "(--epochs), second-look epochs (--second-look-epochs) or preclassifier epochs "
                             "(--preclassifier-epochs)")
        for name, epochs in (("second-look", self.second_look_epochs), ("preclassifier", self.preclassifier_epochs)):
            if epochs < 0:
                raise ValueError(f"{name} epochs {epochs}: give 0 (none) or more")
        if not (self.learning_rate > 0 and self.weight_decay >= 0):
            raise ValueError(f"learning rate {self.learning_rate} must be above 0, weight decay {self.weight_decay} "
                             "not below")
        if not 0 <= self.colour_jitter < 0.5:
            raise ValueError(f"colour jitter {self.colour_jitter}: give 0 (none) up to below 0.5")
        if self.keep not in ("best", "last"):
            raise ValueError(f"keep {self.keep!r}: give best or last")
        if self.minutes is not None and not self.minutes > 0:
            raise ValueError(f"minutes {self.minutes}: give a positive time, or None for every epoch")
