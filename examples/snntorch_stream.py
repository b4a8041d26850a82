"""A snnTorch leaky integrate-and-fire network over a pulse stream's binned events: an outside
stream network for simlidar (docs/streams.md, "Your own stream network").

Entered by its recipe (``examples/snntorch_stream.toml``), whose ``[stream]`` table says what it
reads: every ``bin_ms`` of sensor time, the events of the bin and their nearness, (T, B, 2, H,
W). It returns (spikes, membrane) of its output layer over the T steps, as snnTorch networks
do; simlidar reads the membrane potential at every step as the class scores::

    python benchmark/stream_bench.py DATA --out DIR --models examples/snntorch_stream.toml

Needs ``pip install "simlidar[snntorch]"``.
"""

import math

import snntorch as snn
import torch
from torch import nn


class LeakyStream(nn.Module):
    """inputs - hidden LIF - classes LIF; forward (T, B, 2, H, W) -> (spikes, membrane) of the
    output layer, each (T, B, classes). The output layer does not reset, so that its membrane
    integrates the evidence."""

    def __init__(self, inputs: int, hidden: int, classes: int, beta: float, generator):
        super().__init__()
        self.fc1, self.lif1 = nn.Linear(inputs, hidden), snn.Leaky(beta=beta)
        self.fc2 = nn.Linear(hidden, classes)
        self.lif2 = snn.Leaky(beta=beta, reset_mechanism="none")
        for layer in (self.fc1, self.fc2):  # torch's default initialisation, seeded
            nn.init.kaiming_uniform_(layer.weight, a=math.sqrt(5), generator=generator)
            bound = 1 / math.sqrt(layer.in_features)
            nn.init.uniform_(layer.bias, -bound, bound, generator=generator)

    def forward(self, x: torch.Tensor):
        mem1, mem2 = self.lif1.init_leaky(), self.lif2.init_leaky()  # a fresh state per batch
        spikes, membrane = [], []
        for step in x:  # (B, 2, H, W) a bin of events
            s1, mem1 = self.lif1(self.fc1(step.flatten(1)), mem1)
            s2, mem2 = self.lif2(self.fc2(s1), mem2)
            spikes.append(s2)
            membrane.append(mem2)
        return torch.stack(spikes), torch.stack(membrane)


def build(input_shape, classes, generator=None, hidden=200, beta=0.95):
    """simlidar's builder protocol: (input shape (C, H, W), classes, a seeded generator)."""
    return LeakyStream(math.prod(input_shape), hidden, classes, beta, generator)
