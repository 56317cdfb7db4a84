"""Nearest-neighbour 2x upsampling written as expand + reshape, for an ONNX graph that runs on the Nao's Atom.

OpenVINO's CPU plugin finds no primitive for ONNX ``Resize`` at the Atom's instruction set (SSE4.1/4.2, no AVX): an
FP32 YOLOv8 graph does not compile there at all. The same values come out of an ``Unsqueeze``/``Expand``/``Reshape``
chain, which every engine runs on any x86 CPU. ``benchmarks/bench_robot.py`` measures both.
"""
from __future__ import annotations

import torch
from torch import nn


class NearestUpsample2x(nn.Module):
    """Each pixel repeated into a 2x2 block: ``nn.Upsample(scale_factor=2, mode="nearest")`` exactly."""

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        n, c, h, w = x.shape
        return x[:, :, :, None, :, None].expand(n, c, h, 2, w, 2).reshape(n, c, 2 * h, 2 * w)


def replace_nearest_upsampling(layers: nn.Sequential) -> int:
    """Swap every 2x nearest ``nn.Upsample`` of an Ultralytics layer list for ``NearestUpsample2x`` (keeping the
    attributes Ultralytics routes layers by); returns how many were swapped."""
    swapped = 0
    for index, layer in enumerate(layers):
        if isinstance(layer, nn.Upsample) and layer.mode == "nearest" and layer.scale_factor in (2, 2.0, (2.0, 2.0)):
            replacement = NearestUpsample2x()
            for name in ("f", "i", "type", "np"):
                setattr(replacement, name, getattr(layer, name))
            layers[index] = replacement
            swapped += 1
    return swapped
