"""Annotated pole datasets: the Roboflow "YOLOv8" segmentation layout, COCO import, and checks."""
from detector.datasets.model import Dataset, DatasetError, Instance, Problem, Sample, SPLITS
from detector.datasets.io import load_dataset, write_dataset

__all__ = ["Dataset", "DatasetError", "Instance", "Problem", "Sample", "SPLITS", "load_dataset", "write_dataset"]
