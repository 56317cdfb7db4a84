"""naoslam: the runtime that turns pole detections into range/bearing measurements and runs EKF SLAM.

Runs on the robot: imports only numpy, OpenCV and onnxruntime - never torch, ultralytics or the training side.
"""
