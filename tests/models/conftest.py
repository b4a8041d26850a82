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


@pytest.fixture
def dense_case():
    """``dense_case(rows, n_in, n_out, seed, dtype=float64)``: (input spikes (rows, n_in) in the
    z domain with 25 % silent and, from 4 rows on, an all-silent row, a tie of half a row and a
    row of many ties; weights (n_in, n_out) whose sums let most outputs fire), seeded: the dense
    case that the kernels, the reference and the torch form are held to."""

    def make(rows: int, n_in: int, n_out: int, seed: int, dtype=torch.float64):
        generator = torch.Generator().manual_seed(seed)
        z = torch.exp(3 * torch.rand(rows, n_in, generator=generator, dtype=dtype))
        z[torch.rand(rows, n_in, generator=generator) < 0.25] = torch.inf  # silent inputs
        if rows > 3:
            z[1] = torch.inf  # an all-silent row
            z[2, : n_in // 2] = z[2, 0]  # a tie of half the row
            z[3] = torch.round(z[3] * 2) / 2  # many ties
        w = torch.randn(n_in, n_out, generator=generator, dtype=dtype) / n_in**0.5 + 3.0 / n_in
        return z, w

    return make
