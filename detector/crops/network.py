"""The crop network: a fixed-size crop of a candidate window in, the pole's class (six landmarks or none) and its
box in the crop out. Three strided convolutions and two dense layers, tens of thousands of parameters, so a frame's
dozen crops cost about as much as one small convolution over the frame."""
from __future__ import annotations

import torch
from torch import nn

from naoslam.landmarks import CLASSES

#: The crop's size (width, height): a candidate's window (two bands by six) squeezed to half as wide as tall.
CROP_SIZE_WH = (24, 48)
#: Channels of the three convolutions and width of the hidden dense layer.
CHANNELS = (16, 24, 32)
HIDDEN = 64
#: Outputs per crop: the landmark classes and "no pole", then the box (x0, y0, x1, y1 normalised to the crop).
OUTPUTS = len(CLASSES) + 1 + 4


def _conv(inputs: int, outputs: int) -> nn.Sequential:
    return nn.Sequential(nn.Conv2d(inputs, outputs, 3, stride=2, padding=1, bias=False), nn.BatchNorm2d(outputs),
                         nn.ReLU(inplace=True))


class PoleCropNet(nn.Module):
    """(N, 3, H, W) BGR crops in 0..1 -> (N, 7 + 4): raw class logits, then the box."""

    def __init__(self, size_wh: tuple[int, int] = CROP_SIZE_WH, channels: tuple[int, ...] = CHANNELS,
                 hidden: int = HIDDEN):
        super().__init__()
        if any(side % (1 << len(channels)) for side in size_wh):
            raise ValueError(f"crop size {size_wh}: each side must divide by {1 << len(channels)}")
        self.size_wh = tuple(size_wh)
        widths = (3, *channels)
        self.features = nn.Sequential(*(_conv(a, b) for a, b in zip(widths, widths[1:])))
        cells = (size_wh[0] >> len(channels)) * (size_wh[1] >> len(channels))
        self.head = nn.Sequential(nn.Flatten(), nn.Linear(channels[-1] * cells, hidden), nn.ReLU(inplace=True),
                                  nn.Linear(hidden, OUTPUTS))

    def forward(self, crops: torch.Tensor) -> torch.Tensor:
        return self.head(self.features(crops))


class DeployedCropNet(nn.Module):
    """What the robot runs: class probabilities (softmax) and the box, one (N, 11) output."""

    def __init__(self, network: PoleCropNet):
        super().__init__()
        self.network = network

    def forward(self, crops: torch.Tensor) -> torch.Tensor:
        out = self.network(crops)
        classes = len(CLASSES) + 1
        return torch.cat([torch.softmax(out[:, :classes], dim=1), out[:, classes:]], dim=1)
