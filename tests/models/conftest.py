"""Fixtures of the model tests."""

import pytest
import torch


@pytest.fixture
def conv_case():
    """``conv_case(batch, stride, kernel)``: (input spikes (batch, 2, 9, 11) in the z domain with
    30 % silent, an all-silent second sample and a tie across fields and channels; weights
    (4, 2, kernel, kernel) whose sums let most fields fire), float64, seeded by the stride: the
    convolution case that the kernels, the reference and the torch form are held to."""

    def make(batch: int, stride: int, kernel: int):
        generator = torch.Generator().manual_seed(4 + stride)
        z = torch.exp(3 * torch.rand(batch, 2, 9, 11, generator=generator, dtype=torch.float64))
        z[torch.rand(z.shape, generator=generator) < 0.3] = torch.inf
        if batch > 1:
            z[1] = torch.inf  # an all-silent sample
            z[0, 0, :4] = z[0, 0, 0, 0]  # a tie across fields and channels
        fan_in = 2 * kernel * kernel
        w = torch.randn(4, 2, kernel, kernel, generator=generator, dtype=torch.float64)
        return z, w / fan_in**0.5 + 3.0 / fan_in

    return make
