"""The paper's spiking networks: a dense SNN and a spiking CNN, in the z domain."""

import torch
import torch.nn.functional as F
from torch import nn

from simlidar.errors import ConfigError
from simlidar.models import ttfs
from simlidar.models.layers import ConvTTFS, DenseTTFS
from simlidar.models.protocol import FIRST_SPIKE_TIMES, ModelSpec, class_scores

MAX_SCALE = 80.0  # exp(80) = 5.5e34, below float32's 3.4e38


class SpikingNet(nn.Module):
    """Input delays (B, C, H, W) -> output first-spike times in the z domain (B, classes).

    scale : input spike time t = scale * delay
    silent_from : delays at or above this are no input spike: 1.0 (the physical profile: a
        missing return is no spike) or inf (the paper profile: every pixel spikes). A property
        of the data, not of the recipe: ``train`` sets it from the dataset's ``input_spikes``
        attribute (:func:`simlidar.dataset.loaders.spike_threshold`) and checkpoints keep it.
    direction, missing : which delay spikes first and what a missing return becomes
        (:func:`simlidar.models.ttfs.encode`; the recipe's ``[architecture]`` keys, recorded
        with it in every cell); the defaults are simlidar's encoding, bit for bit
    input_budget : None (every input spike), or a gate that lets only each sample's first
        ``input_budget`` spikes through (:func:`simlidar.models.ttfs.first_spikes`), in
        training and in the event-driven evaluation alike
    input_columns : None (every column), or a gate that lets only the spikes of the image's
        first ``input_columns`` columns (the last axis) through, the rest being no spike
        (:func:`simlidar.models.ttfs.first_columns`). Columns are the sweep's firings in
        order (a scan-timed dataset's ``emission_ns`` grows along them), so on flash delays
        this is the network that per-pixel delay lines make of a scan: it decides once the
        first ``input_columns`` firings are back (benchmark/sweep_decisions.py, docs/snn.md)
    """

    simlidar_spec = ModelSpec(output=FIRST_SPIKE_TIMES)  # first-spike times (z), not logits

    def __init__(
        self,
        layers: list[nn.Module] = (),
        scale: float = 3.0,
        direction: str = ttfs.NEAR_FIRST,
        missing: str = ttfs.AS_VALUE,
        input_budget: int | None = None,
        input_columns: int | None = None,
    ):
        for key, value, allowed in (
            ("direction", direction, ttfs.DIRECTIONS),
            ("missing", missing, ttfs.MISSING),
        ):
            if value not in allowed:
                raise ConfigError(f"{key}={value!r}: expected one of {list(allowed)}")
        if not 0.0 < scale <= MAX_SCALE:
            raise ConfigError(
                f"scale={scale!r}: expected a value in (0, {MAX_SCALE}] so that "
                "exp(scale * delay) stays finite in float32"
            )
        for key, value in (("input_budget", input_budget), ("input_columns", input_columns)):
            if value is not None and (
                isinstance(value, bool) or not isinstance(value, int) or value < 1
            ):
                raise ConfigError(f"{key}={value!r}: expected a whole number >= 1")
        super().__init__()
        self.layers = nn.ModuleList(layers)
        self.scale = scale
        self.silent_from = 1.0
        self.direction = direction
        self.missing = missing
        self.input_budget = input_budget
        self.input_columns = input_columns

    def encoded_shape(self, input_shape) -> tuple[int, int, int]:
        """(C, H, W) of the input spikes of (C, H, W) delays: twice the channels where a missing
        return has a channel of its own (:func:`simlidar.models.ttfs.input_channels`)."""
        c, *rest = input_shape
        return (c * ttfs.input_channels(self.missing), *rest)

    def arriving_fraction(self, input_shape) -> float:
        """The fraction of the inputs that can spike behind the gates: a first dense layer
        starts with weights that let a neuron fire on that many (:class:`DenseTTFS`). Where a
        missing return has a channel of its own, each pixel spikes in one of its two channels:
        one half at most."""
        input_shape = self.encoded_shape(input_shape)
        inputs = int(torch.tensor(input_shape).prod())
        fraction = 1.0 / ttfs.input_channels(self.missing)
        if self.input_budget is not None:
            fraction = min(fraction, self.input_budget / inputs)
        if self.input_columns is not None:
            fraction = min(fraction, self.input_columns / input_shape[-1])
        return fraction

    event_driven = True  # the decision evaluator (simlidar.models.decisions) runs it

    def forward(self, delays: torch.Tensor) -> torch.Tensor:
        return self.spikes(delays)[-1]

    def spikes(self, delays: torch.Tensor) -> list[torch.Tensor]:
        """The input spikes and every layer's output spikes, in the z domain (inf = none)."""
        return self.propagate(self.input_spikes(delays))

    def propagate(self, z: torch.Tensor) -> list[torch.Tensor]:
        """Input spikes ``z`` (B, ...) (z domain) and every layer's output spikes after them,
        computed in the wider of z's and the weights' dtypes: float64 input spikes give the
        exact spike times that the accuracy and the event-driven evaluator are read from
        (:func:`simlidar.bench.scoring.predictions`,
        :func:`simlidar.models.decisions.decide_all`)."""
        out = [z]
        for layer in self.layers:
            out.append(layer(out[-1]))
        return out

    def input_spikes(self, delays: torch.Tensor) -> torch.Tensor:
        """Delays (B, C, H, W) -> the input spikes (z domain, inf = none) by this network's
        encoding (:func:`simlidar.models.ttfs.encode`), through its input budget's gate."""
        z = self.arriving_spikes(delays)
        return z if self.input_budget is None else ttfs.first_spikes(z, self.input_budget)

    def arriving_spikes(self, delays: torch.Tensor) -> torch.Tensor:
        """The input spikes before the input budget's gate: every spike the data send (of the
        first ``input_columns`` columns: the later ones arrive after the decision)."""
        z = ttfs.encode(delays, self.scale, self.silent_from, self.direction, self.missing)
        return z if self.input_columns is None else ttfs.first_columns(z, self.input_columns)

    def penalty(self) -> torch.Tensor:
        """Mean weight-sum penalty over layers (keeps every neuron able to fire)."""
        return sum(ttfs.weight_sum_penalty(m.weight) for m in self.layers) / len(self.layers)

    def simlidar_loss(self, x: torch.Tensor, y: torch.Tensor, training) -> tuple:
        """(cross-entropy, cross-entropy plus the recipe's penalties) on one batch: the
        weight-sum penalty, the target-neuron firing penalty and the early-decision term
        (``training``: a :class:`~simlidar.models.training_config.TrainingConfig`; docs/snn.md)."""
        spikes = self.spikes(x)
        scores = class_scores(spikes[-1], self.simlidar_spec, training.logits, training.logit_scale)
        loss = F.cross_entropy(scores, y)
        total = loss + training.weight_sum_penalty * self.penalty()
        if training.fire_penalty:
            last = self.layers[-1].weight
            fire = ttfs.target_fire_penalty(spikes[-2].flatten(1), last, y, training.fire_margin)
            total = total + training.fire_penalty * fire
        if training.early_penalty:
            early = ttfs.early_term(
                spikes[-1], y, training.early_form, training.early_beta, training.early_margin
            )
            total = total + training.early_penalty * early
        return loss, total


def dense_snn(
    input_shape, classes, generator=None, hidden=(400,), excess=2.0, spread=1.0, **encoding
) -> SpikingNet:
    """Dense TTFS network: inputs (all pixels) - hidden... - classes (256-400-32 on Sim LiDAR).
    ``encoding``: the input's keywords of :class:`SpikingNet` (``scale`` 3.0, ``direction``,
    ``missing``, ``input_budget``, ``input_columns``).

    input_shape : (C, H, W) of one delay image, from the dataset; its C H W pixels are the
        inputs (twice as many where a missing return has a channel of its own)
    classes : the output neurons, one per class
    generator : the ``torch.Generator`` the initial weights are drawn from (None: torch's global
        random state)
    hidden : the widths of the hidden dense TTFS layers
    excess, spread : each layer's initial weights are N((1 + excess) / m, spread / sqrt(m)), m
        its inputs (the first layer's times the fraction that can spike behind the input gates),
        so that every neuron can fire from the start (:class:`~simlidar.models.layers.DenseTTFS`)
    """
    net = SpikingNet(**encoding)
    sizes = [int(torch.tensor(net.encoded_shape(input_shape)).prod())] + list(hidden) + [classes]
    arriving = [net.arriving_fraction(input_shape)] + [1.0] * len(hidden)
    net.layers.extend(
        DenseTTFS(a, b, excess, spread, generator, f) for a, b, f in zip(sizes, sizes[1:], arriving)
    )
    return net


def spiking_cnn(
    input_shape,
    classes,
    generator=None,
    conv=((48, 5, 2), (24, 5, 2)),
    dense=(256,),
    excess=2.0,
    spread=1.0,
    **encoding,
) -> SpikingNet:
    """Spiking CNN: TTFS convolutions (channels, kernel, stride; padded with "no spike"),
    then dense TTFS layers (the paper's KITTI network: 48 and 24 channels of 5x5 stride 2,
    dense 256, dense C). ``encoding``: as :func:`dense_snn`'s.

    input_shape : (C, H, W) of one delay image, from the dataset (twice the channels reach the
        first convolution where a missing return has a channel of its own)
    classes : the output neurons, one per class
    generator : the ``torch.Generator`` the initial weights are drawn from (None: torch's global
        random state)
    conv : (channels, kernel, stride) of each TTFS convolution, in order, each padded by
        kernel // 2 of "no spike"
    dense : the widths of the hidden dense TTFS layers after the convolutions
    excess, spread : the initial weights as :func:`dense_snn`'s, m being a convolution's fan-in
        (C_in k k) or a dense layer's inputs; behind an input gate, only a network without
        convolutions counts its first layer's inputs by the fraction that can spike
    """
    net = SpikingNet(**encoding)
    c, h, w = net.encoded_shape(input_shape)
    layers: list[nn.Module] = []
    # behind a gate only a first dense layer starts for the inputs that arrive: a
    # convolution's patch arrives together or not at all (near returns first: the object and
    # the road close by), and scaled for the whole image's fraction its neurons blew up
    # (benchmark/results/early-objectives-crops/scaled-init/)
    arriving = 1.0 if conv else net.arriving_fraction(input_shape)
    patch = 1.0 / ttfs.input_channels(net.missing)  # of the first patch's inputs, one a pixel
    for channels, kernel, stride in conv:
        pad = kernel // 2
        layers.append(ConvTTFS(c, channels, kernel, stride, pad, excess, spread, generator, patch))
        patch = 1.0
        c = channels
        h, w = (h + 2 * pad - kernel) // stride + 1, (w + 2 * pad - kernel) // stride + 1
    sizes = [c * h * w] + list(dense) + [classes]
    arriving = [arriving] + [1.0] * len(dense)  # the first dense layer's, without a convolution
    layers += [
        DenseTTFS(a, b, excess, spread, generator, f) for a, b, f in zip(sizes, sizes[1:], arriving)
    ]
    net.layers.extend(layers)
    return net
