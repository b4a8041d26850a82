"""Networks over a whole pulse stream (docs/streams.md, "Sequence networks"): they read a
stream as a sequence of steps and give class scores at every step, so that their answer can
change as the pulses come.

A stream network's recipe says what it reads in its ``[stream]`` table (a
:class:`StreamSpec`; a recipe without one is a window model's):

    input    "rotations"  (R, B, 1, H, W): each rotation's window, the pulses' times of flight
                          over ``tof_max_ns`` (1.0: no return), one step a rotation; the answer
                          of step r comes when rotation r's frame is complete (a frame clock)
             "bins"       (T, B, 2, H, W): the events binned in steps of ``bin_ms`` of sensor
                          time from the stream's first firing; channel 0 the events of the bin
                          at each pixel, channel 1 their nearness, 1 - time of flight over
                          ``tof_max_ns`` (0 where none); the answer of step k comes at the
                          bin's end
    bin_ms   a bin's length, ms ("bins")

``forward`` returns the class scores at every step, (T, B, classes), or a tuple whose last item
they are (snnTorch's (spikes, membrane): the membrane potential is read). The class at a step is
the highest score; a step whose scores are all equal (nothing seen yet) gives no answer.

Two are shipped, each in plain torch: :class:`RotationGRU`, a convolutional encoder of each
rotation's window and a GRU over the rotations (a frame-based recurrent network), and
:class:`LIFStream`, convolutional leaky integrate-and-fire layers over the binned events with a
leaky, non-spiking readout (a time-stepped spiking network, trained with a surrogate
gradient: Neftci, Mostafa and Zenke 2019, "Surrogate gradient learning in spiking neural
networks", IEEE Signal Processing Magazine 36(6); the fast-sigmoid surrogate of Zenke and
Ganguli 2018, "SuperSpike", Neural Computation 30(6)).
"""

import math

import torch
from torch import nn

from simlidar.errors import ConfigError
from simlidar.models.conventional import init_weights
from simlidar.models.layers import check_layer


def scores_of(out) -> torch.Tensor:
    """A stream network's (T, B, classes) scores: its output, or the last item of a tuple."""
    if isinstance(out, tuple | list):
        out = out[-1]
    if not isinstance(out, torch.Tensor) or out.dim() != 3:
        got = tuple(out.shape) if isinstance(out, torch.Tensor) else type(out).__name__
        raise ConfigError(f"a stream network returned {got}; expected (T, B, classes) scores")
    return out


def _encoder(channels: int, height: int, width: int, conv) -> tuple[list[nn.Module], int]:
    """Convolutions (channels, kernel, stride) with zero padding kernel // 2: the layers (no
    activation) and the flattened size of their output."""
    layers = []
    for out, kernel, stride in conv:
        pad = kernel // 2
        check_layer(channels * kernel * kernel, out, "convolution")
        layers.append(nn.Conv2d(channels, out, kernel, stride, pad))
        channels = out
        height = (height + 2 * pad - kernel) // stride + 1
        width = (width + 2 * pad - kernel) // stride + 1
    return layers, channels * height * width


def _steps(layer: nn.Module, x: torch.Tensor) -> torch.Tensor:
    """A stateless layer applied to every step of (T, B, ...) at once."""
    y = layer(x.reshape(-1, *x.shape[2:]))
    return y.reshape(*x.shape[:2], *y.shape[1:])


class RotationGRU(nn.Module):
    """Each rotation's window through convolutions (ReLU) and a dense layer, then a GRU over the
    rotations and a linear read-out at every rotation: (R, B, 1, H, W) -> (R, B, classes)."""

    def __init__(self, input_shape, classes, generator, conv, dense, hidden):
        super().__init__()
        c, h, w = input_shape
        layers, size = _encoder(c, h, w, conv)
        check_layer(size, dense, "dense layer")
        encoder = []
        for layer in layers:
            encoder += [layer, nn.ReLU()]
        self.encoder = nn.Sequential(*encoder, nn.Flatten(), nn.Linear(size, dense), nn.ReLU())
        check_layer(dense, hidden, "GRU")
        self.gru = nn.GRU(dense, hidden)
        self.out = nn.Linear(hidden, classes)
        init_weights(self, generator)
        bound = 1.0 / math.sqrt(hidden)  # torch's GRU initialisation, seeded
        for p in self.gru.parameters():
            nn.init.uniform_(p, -bound, bound, generator=generator)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        features = _steps(self.encoder, x)  # (R, B, dense)
        states, _ = self.gru(features)
        return self.out(states)


class _Spike(torch.autograd.Function):
    """Heaviside spike of v - threshold, with the fast-sigmoid surrogate gradient."""

    SLOPE = 10.0  # SuperSpike's beta: the surrogate's sharpness (1 / membrane units)

    @staticmethod
    def forward(ctx, v):
        ctx.save_for_backward(v)
        return (v > 0).to(v.dtype)

    @staticmethod
    def backward(ctx, grad):
        (v,) = ctx.saved_tensors
        return grad / (1.0 + _Spike.SLOPE * v.abs()) ** 2


class _Leak(nn.Module):
    """A learnable decay per channel, beta = sigmoid(rho), started at ``beta``."""

    def __init__(self, channels: int, beta: float):
        super().__init__()
        self.rho = nn.Parameter(torch.full((channels,), math.log(beta / (1.0 - beta))))

    def beta(self, shape) -> torch.Tensor:
        view = [1] * len(shape)
        view[1] = shape[1]  # (B, channels, ...): one decay a channel
        return torch.sigmoid(self.rho).reshape(view)


def lif(currents: torch.Tensor, leak: _Leak) -> torch.Tensor:
    """Spikes of leaky integrate-and-fire neurons driven by (T, B, channels, ...) currents:
    v <- beta v + I; a spike where v passes 1, then v <- v - 1 (reset by subtraction)."""
    beta = leak.beta(currents.shape[1:])
    v = torch.zeros_like(currents[0])
    spikes = []
    for current in currents:
        v = beta * v + current
        s = _Spike.apply(v - 1.0)
        v = v - s
        spikes.append(s)
    return torch.stack(spikes)


def leaky_readout(currents: torch.Tensor, leak: _Leak) -> torch.Tensor:
    """The membrane of leaky integrators that never spike, (T, B, classes): v <- beta v + I."""
    beta = leak.beta(currents.shape[1:])
    v = torch.zeros_like(currents[0])
    out = []
    for current in currents:
        v = beta * v + current
        out.append(v)
    return torch.stack(out)


class LIFStream(nn.Module):
    """Convolutional leaky integrate-and-fire layers over binned events, a dense LIF layer and a
    leaky integrator read-out: (T, B, 2, H, W) -> (T, B, classes) membrane potentials. Each
    layer's decay per step is learned per channel (started at ``beta``; ``beta_out`` for the
    read-out), so that a layer can hold what a window showed over the rotation's silent
    part. The spiking layers' initial weights are torchvision's scheme times ``gain``: the
    events are sparse in time (a window's 32 columns fire over about 10 ms of each 100 ms
    rotation, a few columns a 1 ms bin), and at gain 1 the second layer never reaches its
    threshold (measured on the benchmark's streams: no spike in 300 steps; gain 4: about 1 % of
    the steps of every layer), so that no gradient but the surrogate's reaches it."""

    def __init__(self, input_shape, classes, generator, conv, dense, beta, beta_out, gain):
        super().__init__()
        c, h, w = input_shape
        layers, size = _encoder(c, h, w, conv)
        check_layer(size, dense, "dense layer")
        self.convs = nn.ModuleList(layers)
        self.conv_leaks = nn.ModuleList(_Leak(layer.out_channels, beta) for layer in layers)
        self.dense = nn.Linear(size, dense)
        self.dense_leak = _Leak(dense, beta)
        self.out = nn.Linear(dense, classes)
        self.out_leak = _Leak(classes, beta_out)
        init_weights(self, generator)
        with torch.no_grad():
            for layer in (*self.convs, self.dense):
                layer.weight.mul_(gain)
                layer.bias.mul_(gain)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        for conv, leak in zip(self.convs, self.conv_leaks, strict=True):
            x = lif(_steps(conv, x), leak)
        x = lif(_steps(self.dense, x.flatten(2)), self.dense_leak)
        return leaky_readout(_steps(self.out, x), self.out_leak)


def _decay(value, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not 0 < value < 1:
        raise ConfigError(f"{name}={value!r}: expected a decay per step in (0, 1)")
    return float(value)


def rotation_gru(
    input_shape, classes, generator=None, conv=((16, 5, 2), (32, 5, 2)), dense=128, hidden=128
):
    """The builder of :class:`RotationGRU` (the registry's ``gru_rotations``).

    input_shape, classes, generator : the registry's (C, H, W), classes and seeded generator
    conv : the encoder's convolutions, (channels, kernel, stride) each
    dense, hidden : the encoder's dense layer and the GRU's state, units
    """
    return RotationGRU(input_shape, classes, generator, conv, dense, hidden)


def lif_stream(
    input_shape,
    classes,
    generator=None,
    conv=((16, 5, 2), (32, 5, 2)),
    dense=128,
    beta=0.95,
    beta_out=0.99,
    gain=4.0,
):
    """The builder of :class:`LIFStream` (the registry's ``lif_stream``).

    input_shape, classes, generator : the registry's (C, H, W), classes and seeded generator
    conv : the LIF convolutions, (channels, kernel, stride) each
    dense : the dense LIF layer's units
    beta, beta_out : the LIF layers' and the read-out's decay per step when training starts
    gain : the spiking layers' initial weights over torchvision's scheme
    """
    if isinstance(gain, bool) or not isinstance(gain, int | float) or not 0 < gain <= 100:
        raise ConfigError(f"gain={gain!r}: expected a number in (0, 100]")
    return LIFStream(
        input_shape,
        classes,
        generator,
        conv,
        dense,
        _decay(beta, "beta"),
        _decay(beta_out, "beta_out"),
        float(gain),
    )
