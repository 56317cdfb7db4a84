"""ONNX export of trained checkpoints, verification against PyTorch, and INT8 quantisation."""
