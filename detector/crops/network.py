"""The crop network: a fixed-size crop of a candidate window in, the pole's class (six landmarks or none) and its
box in the crop out. A few 3x3 convolutions (the first may keep the crop's full resolution, the rest halve it) and
two dense layers, tens of thousands of parameters, so a frame's dozen crops cost about as much as one small
convolution over the frame. Optionally each crop's brightness and contrast are normalised inside the graph, so
exposure and back light move the input less."""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import torch
from torch import nn

from naoslam.landmarks import CLASSES

#: Outputs per crop: the landmark classes and "no pole", then the box (x0, y0, x1, y1 normalised to the crop).
OUTPUTS = len(CLASSES) + 1 + 4
#: Added to a crop's standard deviation before dividing by it (a flat crop stays flat, not infinite).
NORMALISE_EPSILON = 0.02


@dataclass(frozen=True)
class CropArchitecture:
    """The crop network's shape: the crop size (width, height), each convolution's channels and stride, the hidden
    dense layer's width, and whether each crop is normalised to zero mean and unit spread first."""

    size_wh: tuple[int, int] = (24, 48)
    channels: tuple[int, ...] = (16, 24, 32)
    strides: tuple[int, ...] = (2, 2, 2)
    hidden: int = 64
    normalise: bool = False

    def __post_init__(self) -> None:
        if len(self.channels) != len(self.strides) or any(s not in (1, 2) for s in self.strides):
            raise ValueError(f"strides {self.strides}: one stride of 1 or 2 per convolution ({len(self.channels)})")
        if any(side % self.reduction for side in self.size_wh):
            raise ValueError(f"crop size {self.size_wh}: each side must divide by {self.reduction}")

    @property
    def reduction(self) -> int:
        """How many crop pixels one cell of the last convolution spans along each side."""
        return math.prod(self.strides)

    def to_dict(self) -> dict:
        return {key: list(value) if isinstance(value, tuple) else value for key, value in asdict(self).items()}

    @classmethod
    def from_dict(cls, record: dict) -> "CropArchitecture":
        """An architecture from :meth:`to_dict` (a checkpoint's; one from before strides and normalising were
        recorded had three stride-2 convolutions and no normalising)."""
        channels = tuple(record["channels"])
        return cls(tuple(record["size_wh"]), channels, tuple(record.get("strides", (2,) * len(channels))),
                   int(record["hidden"]), bool(record.get("normalise", False)))


#: The shipped robot model's architecture: a fourth convolution at the third one's resolution, crops normalised
#: (docs/robot-model.md, "The deciding table").
ARCHITECTURE = CropArchitecture(channels=(16, 24, 32, 48), strides=(2, 2, 1, 2), normalise=True)
#: The crop's size (width, height): a candidate's window (two bands by six) squeezed to half as wide as tall.
CROP_SIZE_WH = ARCHITECTURE.size_wh


def _conv(inputs: int, outputs: int, stride: int) -> nn.Sequential:
    return nn.Sequential(nn.Conv2d(inputs, outputs, 3, stride=stride, padding=1, bias=False),
                         nn.BatchNorm2d(outputs), nn.ReLU(inplace=True))


class Normalise(nn.Module):
    """Each crop less its mean over every pixel and channel, divided by its standard deviation: brightness and
    contrast gone, the colours' ratios kept. The spread is the root of the mean square less the squared mean:
    written as the mean of squared deviations, OpenVINO fuses the pattern into an MVN node that fails under the Atom's
    SSE4.1 cap."""

    def forward(self, crops: torch.Tensor) -> torch.Tensor:
        mean = crops.mean(dim=(1, 2, 3), keepdim=True)
        square = (crops * crops).mean(dim=(1, 2, 3), keepdim=True)
        spread = (square - mean * mean).clamp(min=0).sqrt()
        return (crops - mean) / (spread + NORMALISE_EPSILON)


class PoleCropNet(nn.Module):
    """(N, 3, H, W) BGR crops in 0..1 -> (N, 7 + 4): raw class logits, then the box."""

    def __init__(self, architecture: CropArchitecture = ARCHITECTURE):
        super().__init__()
        self.architecture = architecture
        self.size_wh = architecture.size_wh
        widths = (3, *architecture.channels)
        self.normalise = Normalise() if architecture.normalise else nn.Identity()
        self.features = nn.Sequential(*(_conv(a, b, s) for a, b, s in zip(widths, widths[1:], architecture.strides)))
        cells = (self.size_wh[0] // architecture.reduction) * (self.size_wh[1] // architecture.reduction)
        self.head = nn.Sequential(nn.Flatten(), nn.Linear(architecture.channels[-1] * cells, architecture.hidden),
                                  nn.ReLU(inplace=True), nn.Linear(architecture.hidden, OUTPUTS))

    def forward(self, crops: torch.Tensor) -> torch.Tensor:
        return self.head(self.features(self.normalise(crops)))


class DeployedCropNet(nn.Module):
    """What the robot runs: class probabilities (softmax) and the box, one (N, 11) output."""

    def __init__(self, network: PoleCropNet):
        super().__init__()
        self.network = network

    def forward(self, crops: torch.Tensor) -> torch.Tensor:
        out = self.network(crops)
        classes = len(CLASSES) + 1
        return torch.cat([torch.softmax(out[:, :classes], dim=1), out[:, classes:]], dim=1)
