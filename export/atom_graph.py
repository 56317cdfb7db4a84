"""Rewrites of a YOLOv8-seg network for the Nao's Atom: the same values, from operators with fast SSE4.1 kernels.

OpenVINO's CPU plugin (oneDNN) capped at the Atom's instruction set (SSE4.1/4.2, no AVX) has no primitive for ONNX
``Resize``, and falls back to slow generic GEMM for a convolution whose output channels are not a multiple of 8 and
for ``ConvTranspose``. Three rewrites, each exact up to float rounding, applied to the PyTorch model before ONNX export:

- nearest 2x upsampling as expand + reshape (``Resize`` does not compile under the cap at all);
- the 1x1 convolutions that end the class branches and the distribution-focal-loss decode, padded with zero
  filters to 8 output channels and sliced back (a sixth of the robot model's time before);
- the prototype branch's 2x2 stride-2 ``ConvTranspose`` as a 1x1 convolution to four times the channels followed by
  a pixel shuffle (``DepthToSpace``).

``benchmarks/bench_robot.py`` measures the result; ``docs/robot-model.md`` gives the per-layer figures.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from torch import nn

#: oneDNN's SSE4.1 convolution kernels work in blocks of 8 channels.
CHANNEL_BLOCK = 8


class NearestUpsample2x(nn.Module):
    """Each pixel repeated into a 2x2 block: ``nn.Upsample(scale_factor=2, mode="nearest")`` exactly."""

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        n, c, h, w = x.shape
        return x[:, :, :, None, :, None].expand(n, c, h, 2, w, 2).reshape(n, c, 2 * h, 2 * w)


class BlockPaddedConv(nn.Module):
    """A convolution with zero filters appended up to a multiple of ``CHANNEL_BLOCK`` outputs, sliced back to the
    original outputs: the same values, computed by the blocked kernel instead of a generic GEMM."""

    def __init__(self, conv: nn.Conv2d):
        super().__init__()
        self.out_channels = conv.out_channels
        padded = math.ceil(conv.out_channels / CHANNEL_BLOCK) * CHANNEL_BLOCK
        self.conv = nn.Conv2d(conv.in_channels, padded, conv.kernel_size, conv.stride, conv.padding,
                              bias=conv.bias is not None).requires_grad_(False)
        with torch.no_grad():
            self.conv.weight.zero_()
            self.conv.weight[:conv.out_channels] = conv.weight
            if conv.bias is not None:
                self.conv.bias.zero_()
                self.conv.bias[:conv.out_channels] = conv.bias

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.conv(x)[:, :self.out_channels]


class ShuffleUpsample(nn.Module):
    """A 2x2 stride-2 ``ConvTranspose2d`` as a 1x1 convolution to 4x the channels and a pixel shuffle: each input
    pixel's 2x2 output block is four output channels of the 1x1 convolution."""

    def __init__(self, transposed: nn.ConvTranspose2d):
        super().__init__()
        if transposed.kernel_size != (2, 2) or transposed.stride != (2, 2) or transposed.padding != (0, 0):
            raise ValueError(f"{transposed}: only a 2x2 stride-2 transposed convolution without padding is rewritten")
        channels_in, channels_out = transposed.in_channels, transposed.out_channels
        self.conv = nn.Conv2d(channels_in, 4 * channels_out, 1, bias=transposed.bias is not None).requires_grad_(False)
        with torch.no_grad():  # weight (in, out, dy, dx) -> (out * 4 + dy * 2 + dx, in), pixel_shuffle's order
            self.conv.weight.copy_(transposed.weight.permute(1, 2, 3, 0).reshape(4 * channels_out, channels_in, 1, 1))
            if transposed.bias is not None:
                self.conv.bias.copy_(transposed.bias.repeat_interleave(4))
        self.shuffle = nn.PixelShuffle(2)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.shuffle(self.conv(x))


@dataclass(frozen=True)
class Rewrites:
    """How many modules each rewrite replaced."""

    upsampling: int
    padded_convolutions: int
    transposed_convolutions: int


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


def rewrite_for_atom(layers: nn.Sequential) -> Rewrites:
    """Apply every rewrite to an Ultralytics segmentation model's layer list (its last layer the ``Segment`` head),
    in place, for export only (the padded filters are frozen)."""
    head = layers[-1]
    padded = 0
    for branch in getattr(head, "cv3", ()):
        if isinstance(branch[-1], nn.Conv2d) and branch[-1].out_channels % CHANNEL_BLOCK:
            branch[-1] = BlockPaddedConv(branch[-1])
            padded += 1
    dfl = getattr(head, "dfl", None)
    if isinstance(getattr(dfl, "conv", None), nn.Conv2d) and dfl.conv.out_channels % CHANNEL_BLOCK:
        dfl.conv = BlockPaddedConv(dfl.conv)
        padded += 1
    transposed = 0
    proto = getattr(head, "proto", None)
    if isinstance(getattr(proto, "upsample", None), nn.ConvTranspose2d):
        proto.upsample = ShuffleUpsample(proto.upsample)
        transposed += 1
    return Rewrites(replace_nearest_upsampling(layers), padded, transposed)
