"""A snnTorch leaky integrate-and-fire network for simlidar: 256-400-C, latency-coded inputs.

Entered into the benchmark by its recipe (``examples/snntorch_lif.toml``)::

    simlidar bench --models examples/snntorch_lif.toml --dataset data/<dataset>

It declares what it is (:class:`simlidar.models.protocol.ModelSpec`): output spikes over
``steps`` time steps, fed latency-coded spike trains (each pixel spikes once, the nearest
returns first), read out by spike count (a rate-decoded network: its first output spike is a
poor decision). Needs ``pip install "simlidar[snntorch]"``.
"""

import math

import snntorch as snn
import torch
from torch import nn

from simlidar.models.protocol import ModelSpec


class LeakyMLP(nn.Module):
    """inputs - hidden LIF - classes LIF; forward (T, B, 1, H, W) -> (spikes, membrane) of the
    output layer, each (T, B, classes)."""

    def __init__(self, inputs: int, hidden: int, classes: int, beta: float, steps: int, generator):
        super().__init__()
        self.simlidar_spec = ModelSpec(
            output="stepped_spikes", encoding="latency", steps=steps, readout="spike_count"
        )
        self.fc1, self.lif1 = nn.Linear(inputs, hidden), snn.Leaky(beta=beta)
        self.fc2, self.lif2 = nn.Linear(hidden, classes), snn.Leaky(beta=beta)
        for layer in (self.fc1, self.fc2):  # torch's default initialisation, seeded
            nn.init.kaiming_uniform_(layer.weight, a=math.sqrt(5), generator=generator)
            bound = 1 / math.sqrt(layer.in_features)
            nn.init.uniform_(layer.bias, -bound, bound, generator=generator)

    def forward(self, x: torch.Tensor):
        mem1, mem2 = self.lif1.init_leaky(), self.lif2.init_leaky()  # a fresh state per batch
        spikes, membrane = [], []
        for step in x:  # (B, 1, H, W) a time step
            s1, mem1 = self.lif1(self.fc1(step.flatten(1)), mem1)
            s2, mem2 = self.lif2(self.fc2(s1), mem2)
            spikes.append(s2)
            membrane.append(mem2)
        return torch.stack(spikes), torch.stack(membrane)


def build(input_shape, classes, generator=None, hidden=400, beta=0.9, steps=25):
    """simlidar's builder protocol: (input shape (C, H, W), classes, a seeded generator)."""
    return LeakyMLP(math.prod(input_shape), hidden, classes, beta, steps, generator)
