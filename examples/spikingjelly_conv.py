"""A SpikingJelly convolutional spiking network for simlidar: conv 5x5/2 - LIF - C LIF,
multi-step, latency-coded inputs.

Entered into the benchmark by its recipe (``examples/spikingjelly_conv.toml``)::

    simlidar bench --models examples/spikingjelly_conv.toml --dataset data/<dataset>

The same protocol as ``snntorch_lif.py`` (output spikes over time steps, latency-coded inputs,
spike-count readout, ties to the higher membrane potential at the last step), written with
SpikingJelly's multi-step layers (``step_mode="m"``): each layer takes the whole (T, B, ...)
spike train at once. Its neurons keep their membrane potential between calls; simlidar resets
them (``MemoryModule.reset()``) before every forward pass of the model, as SpikingJelly's
``functional.reset_net`` would, so the model need not. Needs
``pip install "simlidar[spikingjelly]"``.
"""

import math

import torch
from spikingjelly.activation_based import layer, neuron, surrogate
from torch import nn

from simlidar.models.protocol import ModelSpec


class ConvLIF(nn.Module):
    """conv 5x5 stride 2 - LIF - flatten - linear - classes LIF; forward (T, B, C, H, W) ->
    (spikes, membrane) of the output neurons, each (T, B, classes)."""

    def __init__(self, input_shape, channels, classes, tau, gain, steps, generator):
        super().__init__()
        self.simlidar_spec = ModelSpec(
            output="stepped_spikes", encoding="latency", steps=steps, readout="spike_count"
        )
        c, h, w = input_shape
        lif = dict(tau=tau, surrogate_function=surrogate.ATan(), step_mode="m")
        self.conv = layer.Conv2d(c, channels, 5, stride=2, padding=2, step_mode="m")
        self.lif1 = neuron.LIFNode(**lif)
        self.flat = layer.Flatten(step_mode="m")
        self.fc = layer.Linear(
            channels * math.ceil(h / 2) * math.ceil(w / 2), classes, step_mode="m"
        )
        self.lif2 = neuron.LIFNode(store_v_seq=True, **lif)  # keeps its membrane over the steps
        self.gain = gain  # input current per spike: about one in seven neurons fires a step
        for weights in (self.conv, self.fc):  # torch's default initialisation, seeded
            nn.init.kaiming_uniform_(weights.weight, a=math.sqrt(5), generator=generator)
            fan_in = weights.weight[0].numel()
            nn.init.uniform_(
                weights.bias, -1 / math.sqrt(fan_in), 1 / math.sqrt(fan_in), generator=generator
            )

    def forward(self, x: torch.Tensor):
        hidden = self.lif1(self.gain * self.conv(x))  # (T, B, channels, H / 2, W / 2)
        spikes = self.lif2(self.gain * self.fc(self.flat(hidden)))
        return spikes, self.lif2.v_seq


def build(input_shape, classes, generator=None, channels=8, tau=2.0, gain=10.0, steps=25):
    """simlidar's builder protocol: (input shape (C, H, W), classes, a seeded generator)."""
    return ConvLIF(tuple(input_shape), channels, classes, tau, gain, steps, generator)
