"""Where a training run starts: the pole-pretrained checkpoint shipped with the package, a given checkpoint, or a
model's YAML. Torch-free, so commands that only need the path (shipping, the demo's stage keys) load no framework."""
from __future__ import annotations

from pathlib import Path

from detector.model_files import SHIPPED_WEIGHTS, run_checkpoint

#: The shipped accurate model's architecture.
SHIPPED_ARCHITECTURE = "yolov8n-seg"
#: ``--weights`` value that trains from the YAML instead.
SCRATCH = "scratch"


def starting_point(model: str | None, weights: str | None) -> tuple[str, Path | None]:
    """The architecture and checkpoint a run starts from.

    No ``weights``: the shipped pole checkpoint when the architecture is its own (or not given), else the YAML.
    ``weights="scratch"``: the YAML of ``model`` (default the shipped architecture). Otherwise the given checkpoint
    (or a run folder's best one).
    """
    if weights == SCRATCH:
        return model or SHIPPED_ARCHITECTURE, None
    if weights is not None:
        return model or SHIPPED_ARCHITECTURE, run_checkpoint(weights)
    if model in (None, SHIPPED_ARCHITECTURE):
        if not SHIPPED_WEIGHTS.is_file():
            raise FileNotFoundError(f"{SHIPPED_WEIGHTS}: the shipped pole checkpoint is missing - reinstall nao-poles "
                                    "or pass --weights scratch")
        return SHIPPED_ARCHITECTURE, SHIPPED_WEIGHTS
    return model, None
