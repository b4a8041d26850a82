"""Thin ``nn.Module`` wrappers over :mod:`simlidar.models.ttfs` (the equations live there)."""

import math

import torch
from torch import nn

from simlidar.models import ttfs


class DenseTTFS(nn.Module):
    """Dense time-to-first-spike layer: see :func:`simlidar.models.ttfs.dense`.

    Weights start at N(mean, std) with mean = excess / n_in and std = spread / sqrt(n_in), so
    that a neuron's total weight is about 1 + excess: every neuron can fire from the start.
    """

    def __init__(
        self,
        n_in: int,
        n_out: int,
        excess: float = 2.0,
        spread: float = 1.0,
        generator: torch.Generator | None = None,
    ):
        super().__init__()
        mean, std = (1.0 + excess) / n_in, spread / math.sqrt(n_in)
        w = torch.randn(n_in, n_out, generator=generator) * std + mean
        self.weight = nn.Parameter(w)

    def forward(self, z: torch.Tensor) -> torch.Tensor:
        return ttfs.dense(z.flatten(1), self.weight)


class ConvTTFS(nn.Module):
    """2D convolutional time-to-first-spike layer: see :func:`simlidar.models.ttfs.conv2d`."""

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
    ):
        super().__init__()
        fan_in = c_in * kernel * kernel
        mean, std = (1.0 + excess) / fan_in, spread / math.sqrt(fan_in)
        w = torch.randn(c_out, c_in, kernel, kernel, generator=generator) * std + mean
        self.weight = nn.Parameter(w)
        self.stride, self.padding = stride, padding

    def forward(self, z: torch.Tensor) -> torch.Tensor:
        return ttfs.conv2d(z, self.weight, self.stride, self.padding)
