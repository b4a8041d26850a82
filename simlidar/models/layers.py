"""Thin ``nn.Module`` wrappers over :mod:`simlidar.models.ttfs` (the equations live there)."""

import math

import torch
from torch import nn

from simlidar.errors import ConfigError
from simlidar.models import ttfs
from simlidar.resources import check_memory

# a weight is held four times while a model trains: itself, its gradient and Adam's two moments
TRAINING_COPIES = 4


def check_layer(n_in: int, n_out: int, what: str) -> None:
    """Refuse a layer of ``n_in`` inputs (a convolution's fan-in) and ``n_out`` outputs before
    its weights are allocated: a ConfigError for a size below 1 (``hidden = [0]`` divided by
    zero), a ResourceError when its float32 weights, held :data:`TRAINING_COPIES` times while
    training, do not fit in this process's memory (``hidden = [100000000]``)."""
    for size in (n_in, n_out):
        if isinstance(size, bool) or not isinstance(size, int) or size < 1:
            raise ConfigError(
                f"{what}: a layer of {n_in!r} inputs and {n_out!r} outputs; expected whole "
                "numbers >= 1 (every layer size in the architecture)"
            )
    check_memory(
        TRAINING_COPIES * 4 * n_in * n_out,
        f"{what}: a {n_in} x {n_out} layer's weights, gradients and optimiser state",
    )


class DenseTTFS(nn.Module):
    """Dense time-to-first-spike layer: see :func:`simlidar.models.ttfs.dense`.

    Weights start at N(mean, std) with mean = (1 + excess) / m and std = spread / sqrt(m), m
    = n_in * arriving, so that the total weight of the inputs that spike is about 1 + excess:
    every neuron can fire from the start. ``arriving``: the fraction of the inputs expected to
    spike (1: all; behind an input budget of k of P inputs, k / P).
    """

    def __init__(
        self,
        n_in: int,
        n_out: int,
        excess: float = 2.0,
        spread: float = 1.0,
        generator: torch.Generator | None = None,
        arriving: float = 1.0,
    ):
        super().__init__()
        check_layer(n_in, n_out, "dense TTFS layer")
        m = n_in * arriving
        mean, std = (1.0 + excess) / m, spread / math.sqrt(m)
        w = torch.randn(n_in, n_out, generator=generator) * std + mean
        self.weight = nn.Parameter(w)

    def forward(self, z: torch.Tensor) -> torch.Tensor:
        return ttfs.dense(z.flatten(1), self.weight)


class ConvTTFS(nn.Module):
    """2D convolutional time-to-first-spike layer: see :func:`simlidar.models.ttfs.conv2d`.
    Weights start as :class:`DenseTTFS`'s, over the kernel's fan-in times ``arriving``, the
    fraction of a patch's inputs expected to spike (1: all; one half where a missing return has
    an input channel of its own, :func:`simlidar.models.ttfs.input_channels`: each pixel
    spikes in one of its two channels)."""

    def __init__(
        self,
        c_in: int,
        c_out: int,
        kernel: int,
        stride: int = 1,
        padding: int = 0,
        excess: float = 2.0,
        spread: float = 1.0,
        generator: torch.Generator | None = None,
        arriving: float = 1.0,
    ):
        super().__init__()
        check_layer(c_in * kernel * kernel, c_out, "TTFS convolution")
        fan_in = c_in * kernel * kernel * arriving
        mean, std = (1.0 + excess) / fan_in, spread / math.sqrt(fan_in)
        w = torch.randn(c_out, c_in, kernel, kernel, generator=generator) * std + mean
        self.weight = nn.Parameter(w)
        self.stride, self.padding = stride, padding

    def forward(self, z: torch.Tensor) -> torch.Tensor:
        return ttfs.conv2d(z, self.weight, self.stride, self.padding)
