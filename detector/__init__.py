"""Training side: datasets, the synthetic pole renderer, training, evaluation and the ``poles`` command line."""
import os

# Ultralytics reads this once, at import: nothing may be downloaded (weights, fonts, AMP check model).
os.environ.setdefault("YOLO_OFFLINE", "true")
