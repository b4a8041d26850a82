"""A Norse leaky integrate-and-fire network for simlidar: 256-400-C, latency-coded inputs.

Entered into the benchmark by its recipe (``examples/norse_lif.toml``)::

    simlidar bench --models examples/norse_lif.toml --dataset data/<dataset>

The same protocol as ``snntorch_lif.py`` (output spikes over time steps, latency-coded inputs,
spike-count readout, ties to the higher membrane potential at the last step), written with
Norse's cells, and trained with its own loss (``simlidar_loss``, which any model may define):
the cross-entropy of the output neurons' spike counts plus a small one on their mean membrane
potential, which gives a gradient while an output neuron is still silent.
Needs ``pip install "simlidar[norse]"``.
"""

import math

import norse.torch as norse
import torch
import torch.nn.functional as F
from torch import nn

from simlidar.models.protocol import ModelSpec


class NorseMLP(nn.Module):
    """inputs - hidden LIF - classes LIF cells; forward (T, B, 1, H, W) -> (spikes, membrane)
    of the output cells, each (T, B, classes)."""

    def __init__(self, inputs: int, hidden: int, classes: int, steps: int, generator):
        super().__init__()
        self.simlidar_spec = ModelSpec(
            output="stepped_spikes", encoding="latency", steps=steps, readout="spike_count"
        )
        self.fc1, self.fc2 = nn.Linear(inputs, hidden), nn.Linear(hidden, classes)
        p = norse.LIFParameters(tau_mem_inv=torch.tensor(200.0), tau_syn_inv=torch.tensor(400.0))
        self.lif1, self.lif2 = norse.LIFCell(p), norse.LIFCell(p)
        for layer in (self.fc1, self.fc2):
            nn.init.kaiming_uniform_(layer.weight, a=math.sqrt(5), generator=generator)
            bound = 1 / math.sqrt(layer.in_features)
            nn.init.uniform_(layer.bias, -bound, bound, generator=generator)
        self.gain = 20.0  # input current per spike: about one in eight hidden neurons fires

    def forward(self, x: torch.Tensor):
        state1 = state2 = None  # Norse cells start from rest when given no state
        spikes, membrane = [], []
        for step in x:
            s1, state1 = self.lif1(self.gain * self.fc1(step.flatten(1)), state1)
            s2, state2 = self.lif2(self.gain * self.fc2(s1), state2)
            spikes.append(s2)
            membrane.append(state2.v)
        return torch.stack(spikes), torch.stack(membrane)

    def simlidar_loss(self, x, y, training):
        """(cross-entropy, total): the count cross-entropy, plus 0.1 x the cross-entropy of
        the membrane potentials averaged over time."""
        spikes, membrane = self(x)
        loss = F.cross_entropy(spikes.sum(0), y)
        return loss, loss + 0.1 * F.cross_entropy(membrane.mean(0), y)


def build(input_shape, classes, generator=None, hidden=400, steps=25):
    """simlidar's builder protocol: (input shape (C, H, W), classes, a seeded generator)."""
    return NorseMLP(math.prod(input_shape), hidden, classes, steps, generator)
