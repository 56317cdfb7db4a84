"""``--device``: refuse a device this machine does not have in one line, before any image is decoded.

Ultralytics finds out only when training starts, after the dataset is read, and then says so in a paragraph; asked
for ``mps`` where there is none, it trains on the CPU without a word. Device strings this module does not know
(Ultralytics' ``-1``: the idlest GPU, ``npu``...) pass through to Ultralytics unchanged.
"""
from __future__ import annotations

import re

import torch

#: A CUDA device list as Ultralytics takes it: ``0``, ``0,1``, ``cuda:0``.
CUDA_DEVICES = re.compile(r"^(?:cuda:)?(\d+(?:,\d+)*)$")
CPU_FIX = "leave --device out to train on the CPU"


def check_device(device: str) -> None:
    """Raise ValueError naming ``device``, what PyTorch sees and the fix, when the device is not on this machine."""
    device = device.strip().lower()
    if device == "mps" and not torch.backends.mps.is_available():
        raise ValueError(f"--device mps: Apple's Metal (MPS) is not available to PyTorch here - fix: {CPU_FIX}")
    cuda = CUDA_DEVICES.match(device)
    if cuda:
        wanted = [int(index) for index in cuda.group(1).split(",")]
        seen = torch.cuda.device_count()
        if max(wanted) >= seen:
            raise ValueError(f"--device {device}: PyTorch {torch.__version__} {_cuda_problem(seen)}")


def _cuda_problem(seen: int) -> str:
    """What keeps PyTorch from the GPUs asked for, and the fix."""
    if seen:
        return f"sees GPUs 0-{seen - 1} only - fix: name GPUs it sees, or {CPU_FIX}"
    if torch.version.cuda is None:
        return f"is built without CUDA - fix: {CPU_FIX}, or install a CUDA build of PyTorch"
    return f"sees no CUDA GPU - fix: {CPU_FIX}, or check the GPU and its driver with nvidia-smi"
