"""The export's rewrites for the Atom give the same values as the layers they replace."""
from __future__ import annotations

import os

import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from export.atom_graph import (BlockPaddedConv, NearestUpsample2x, ShuffleUpsample, replace_nearest_upsampling,
                               rewrite_for_atom)

os.environ.setdefault("YOLO_OFFLINE", "true")


@settings(max_examples=25, deadline=None)
@given(st.integers(1, 4), st.integers(1, 6), st.integers(1, 9), st.integers(1, 9))
def test_nearest_upsample_2x_equals_torch_upsample(batch, channels, height, width):
    x = torch.randn(batch, channels, height, width)
    assert torch.equal(NearestUpsample2x()(x), torch.nn.Upsample(scale_factor=2, mode="nearest")(x))


def test_replacing_upsampling_keeps_ultralytics_routing():
    layers = torch.nn.Sequential(torch.nn.Identity(), torch.nn.Upsample(scale_factor=2, mode="nearest"),
                                 torch.nn.Upsample(scale_factor=2, mode="bilinear"))
    for index, layer in enumerate(layers):
        layer.f, layer.i, layer.type, layer.np = -1, index, type(layer).__name__, 0
    assert replace_nearest_upsampling(layers) == 1
    assert isinstance(layers[1], NearestUpsample2x) and (layers[1].f, layers[1].i) == (-1, 1)
    assert isinstance(layers[2], torch.nn.Upsample)  # bilinear is another operation: left alone


@settings(max_examples=25, deadline=None)
@given(st.integers(1, 12), st.integers(1, 13), st.sampled_from([1, 3]), st.booleans(), st.integers(0, 2**31 - 1))
def test_a_block_padded_convolution_equals_the_convolution(channels_in, channels_out, kernel, bias, seed):
    torch.manual_seed(seed)
    conv = torch.nn.Conv2d(channels_in, channels_out, kernel, padding=kernel // 2, bias=bias)
    padded = BlockPaddedConv(conv)
    assert padded.conv.out_channels % 8 == 0 and padded.conv.out_channels >= channels_out
    x = torch.randn(2, channels_in, 7, 5)
    assert torch.allclose(padded(x), conv(x), atol=1e-6)


@settings(max_examples=25, deadline=None)
@given(st.integers(1, 9), st.integers(1, 9), st.integers(1, 6), st.integers(1, 6), st.integers(0, 2**31 - 1))
def test_a_shuffle_upsample_equals_the_transposed_convolution(channels_in, channels_out, height, width, seed):
    torch.manual_seed(seed)
    transposed = torch.nn.ConvTranspose2d(channels_in, channels_out, 2, 2)
    x = torch.randn(2, channels_in, height, width)
    assert torch.allclose(ShuffleUpsample(transposed)(x), transposed(x), atol=1e-5)


def test_only_a_2x2_stride_2_transposed_convolution_is_rewritten():
    with pytest.raises(ValueError, match="only a 2x2 stride-2"):
        ShuffleUpsample(torch.nn.ConvTranspose2d(4, 4, 3, 2))


@pytest.mark.parametrize("architecture", ["yolov8n-seg", "robot-p4-seg"])
def test_rewriting_a_segmentation_model_keeps_its_outputs(architecture):
    """Every rewrite applied to a whole Ultralytics model (six classes, as the poles): boxes, scores, mask
    coefficients and prototypes unchanged."""
    from ultralytics.nn.tasks import SegmentationModel

    from detector.training.train import architecture_yaml

    torch.manual_seed(3)
    model = SegmentationModel(architecture_yaml(architecture), nc=6, verbose=False).eval()
    x = torch.rand(1, 3, 64, 96)
    with torch.no_grad():
        before = model(x)
        rewrites = rewrite_for_atom(model.model)
        after = model(x)
    assert rewrites.padded_convolutions == len(model.model[-1].cv3) + 1  # each class branch, and the box decode
    assert rewrites.transposed_convolutions == 1 and rewrites.upsampling >= 1
    assert torch.allclose(after[0][0], before[0][0], atol=1e-3)  # decoded boxes (pixels) and scores
    assert torch.allclose(after[0][1], before[0][1], atol=1e-5)  # prototypes
