"""Perception on the robot: from a camera frame to pole detections.

- ``interface.py``: ``PoleDetector``, the one shape of "frame to detections" every front end has;
- ``yolo.py``: ``LandmarkDetector``, the YOLOv8-seg front end (masks; the accurate model);
- ``two_stage.py``: ``CropDetector``, the robot's two-stage front end: pink candidates at full resolution
  (``candidates.py``), fixed-size crops of them (``crops.py``) and a crop network over the crops;
- ``colour_filter.py``: the thesis's colour filter;
- ``loading.py``: ``load_detector``, which opens any of them by name or file;
- what they share: ``detections.py`` (``Detection``), ``pole_model.py`` (an ONNX pole model's session, classes,
  calibration), ``model_info.py`` (its metadata), ``engines.py`` (OpenVINO), ``frames.py`` (the camera's YUYV).
"""
