"""One source for every training default: ``TrainSettings`` and ``poles train``'s flags both read them here.
Torch-free, so the command line builds its parsers without loading a framework."""
from __future__ import annotations

from detector.training.starting_point import SHIPPED_ARCHITECTURE

#: Architecture: the shipped accurate model's, so a run fine-tunes the shipped checkpoint.
MODEL = SHIPPED_ARCHITECTURE
EPOCHS = 100
#: Training image size: the Nao's full frame width, so a 10 px pole stays 10 px.
IMGSZ = 640
BATCH = 8
PATIENCE = 50
SEED = 0
#: Data-loader processes: none is best on two cores.
WORKERS = 0
DEVICE = "cpu"
