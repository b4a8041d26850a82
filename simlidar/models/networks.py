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
    """

    simlidar_spec = ModelSpec(output=FIRST_SPIKE_TIMES)  # first-spike times (z), not logits

    def __init__(
        self,
        layers: list[nn.Module],
        scale: float,
        direction: str = ttfs.NEAR_FIRST,
        missing: str = ttfs.AS_VALUE,
        input_budget: int | None = None,
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
        _check_budget(input_budget)
        super().__init__()
        self.layers = nn.ModuleList(layers)
        self.scale = scale
        self.silent_from = 1.0
        self.direction = direction
        self.missing = missing
        self.input_budget = input_budget

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
        (:func:`simlidar.bench.train.predictions`, :func:`simlidar.models.decisions.decide_all`)."""
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
        """The input spikes before the input budget's gate: every spike the data send."""
        return ttfs.encode(delays, self.scale, self.silent_from, self.direction, self.missing)

    def penalty(self) -> torch.Tensor:
        """Mean weight-sum penalty over layers (keeps every neuron able to fire)."""
        return sum(ttfs.weight_sum_penalty(m.weight) for m in self.layers) / len(self.layers)

    def simlidar_loss(self, x: torch.Tensor, y: torch.Tensor, training) -> tuple:
        """(cross-entropy, cross-entropy plus the recipe's penalties) on one batch: the
        weight-sum penalty, the target-neuron firing penalty and the early-decision term
        (``training``: a :class:`~simlidar.models.training.TrainingConfig`; docs/snn.md)."""
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
    input_shape,
    classes,
    generator=None,
    hidden=(400,),
    scale=3.0,
    excess=2.0,
    spread=1.0,
    direction=ttfs.NEAR_FIRST,
    missing=ttfs.AS_VALUE,
    input_budget=None,
) -> SpikingNet:
    """Dense TTFS network: inputs (all pixels) - hidden... - classes (256-400-32 on Sim LiDAR).
    ``direction``, ``missing`` and ``input_budget``: the input encoding (:class:`SpikingNet`)."""
    sizes = [int(torch.tensor(input_shape).prod())] + list(hidden) + [classes]
    arriving = [_arriving(input_shape, input_budget)] + [1.0] * len(hidden)
    layers = [
        DenseTTFS(a, b, excess, spread, generator, f) for a, b, f in zip(sizes, sizes[1:], arriving)
    ]
    return SpikingNet(layers, scale, direction, missing, input_budget)


def _check_budget(input_budget) -> None:
    if input_budget is not None and (
        isinstance(input_budget, bool) or not isinstance(input_budget, int) or input_budget < 1
    ):
        raise ConfigError(f"input_budget={input_budget!r}: expected a whole number >= 1")


def _arriving(input_shape, input_budget) -> float:
    """The fraction of the inputs that spike behind ``input_budget``: the first layer starts
    with weights that let a neuron fire on that many (:class:`DenseTTFS`)."""
    _check_budget(input_budget)
    inputs = int(torch.tensor(input_shape).prod())
    return 1.0 if input_budget is None else min(1.0, input_budget / inputs)


def spiking_cnn(  # the same keyword arguments as dense_snn on purpose: recipes name them
    input_shape,
    classes,
    generator=None,
    conv=((48, 5, 2), (24, 5, 2)),
    dense=(256,),
    scale=3.0,
    excess=2.0,
    spread=1.0,
    direction=ttfs.NEAR_FIRST,
    missing=ttfs.AS_VALUE,
    input_budget=None,
) -> SpikingNet:
    """Spiking CNN: TTFS convolutions (channels, kernel, stride; padded with "no spike"),
    then dense TTFS layers (the paper's KITTI network: 48 and 24 channels of 5x5 stride 2,
    dense 256, dense C). ``direction``, ``missing`` and ``input_budget``: the input encoding
    (:class:`SpikingNet`)."""
    c, h, w = input_shape
    layers: list[nn.Module] = []
    # behind an input budget only a first dense layer starts for the inputs that arrive: a
    # convolution's patch arrives together or not at all (near returns first: the object and
    # the road close by), and scaled for the whole image's fraction its neurons blew up
    # (benchmark/results/early-objectives-crops/scaled-init/); SpikingNet checks the budget
    arriving = 1.0 if conv else _arriving(input_shape, input_budget)
    for channels, kernel, stride in conv:
        pad = kernel // 2
        layers.append(ConvTTFS(c, channels, kernel, stride, pad, excess, spread, generator))
        c = channels
        h, w = (h + 2 * pad - kernel) // stride + 1, (w + 2 * pad - kernel) // stride + 1
    sizes = [c * h * w] + list(dense) + [classes]
    arriving = [arriving] + [1.0] * len(dense)  # the first dense layer's, without a convolution
    layers += [
        DenseTTFS(a, b, excess, spread, generator, f) for a, b, f in zip(sizes, sizes[1:], arriving)
    ]
    return SpikingNet(layers, scale, direction, missing, input_budget)
