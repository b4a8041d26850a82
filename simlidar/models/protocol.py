"""What a model declares to the harness: what it outputs and which input encoding it wants.

Any ``torch.nn.Module`` can be benchmarked. It declares itself with a class or instance
attribute ``simlidar_spec`` (a :class:`ModelSpec`); a module without one is a conventional
classifier of delay images. A recipe's ``[spec]`` table overrides the declared values, so a
network written for another library can be entered without touching its code.

    output    what ``forward`` returns
      "logits"             (B, classes) scores; the class is the largest
      "first_spike_times"  (B, classes) first output spike times in the z domain of
                           :mod:`simlidar.models.ttfs` (z = exp(t), inf: no spike); the class is
                           the earliest (simlidar's time-to-first-spike networks)
      "stepped_spikes"     (T, B, classes) output spikes over T time steps, or a tuple
                           (spikes, membrane) of two such tensors (snnTorch, Norse, SpikingJelly)
    encoding  what ``forward`` is given, made by simlidar from the file's delays and profile
      "delays"             (B, 1, H, W) float delays in [0, 1], the split's ``delays``
      "latency"            (T, B, 1, H, W) binary spike trains: each pixel spikes once, at step
                           min(floor(delay * T), T - 1), the earliest step for the smallest
                           delay; a pixel the profile reads as no return does not spike
      "events"             (B, H * W, 4) the same spikes as address events in Tonic's ordering
                           (x column, y row, t step, p polarity 0), each sample's sorted by t
                           (then row-major pixel order), padded to H * W rows (one pulse a
                           pixel at most) with rows of -1; :func:`tonic_events` gives each
                           sample as a Tonic event array
    steps     T of the "latency" and "events" encodings
    readout   how a "stepped_spikes" network's decision is read (:func:`readout`)
      "first_spike"        the first step at which any output neuron spikes decides: the
                           class is that neuron; ties (several neurons spike at that step) go to
                           the highest membrane potential at that step when the model returns
                           it, then to the lowest class index; no output spike: no decision
      "spike_count"        the class with the most output spikes over the T steps (ties: the
                           highest membrane potential at the last step, then the lowest index);
                           decided at the last step; no output spike and no membrane: none
      "membrane"           the highest membrane potential at the last step (needs membrane)

Hooks a model may define (each optional):

    simlidar_loss(x, y, training) -> (cross_entropy, total)
        its own training objective on an encoded batch (simlidar's spiking networks add their
        penalties here); default: the cross-entropy of :func:`class_scores`
    simlidar_fit(x_train, y_train, x_val, y_val, generator) -> None
        its own training loop, on encoded tensors; simlidar then scores the validation split
        (recorded) and reads the test split once. A model trained elsewhere, its weights loaded
        by its builder, is scored only with a ``simlidar_fit`` that returns at once.

Neuron state. Every forward call of a benchmarked model is a new batch of samples, whose
neurons start from rest: a model built by :func:`simlidar.models.registry.build_model` has the
state of its stateful modules reset before each forward call (:func:`reset_state`), for
training, scoring and the metrics alike. Those are SpikingJelly's (any subclass of
``spikingjelly.activation_based.base.MemoryModule``, its neurons included: their ``reset()``,
what SpikingJelly's ``functional.reset_net`` calls) and any module that defines
``simlidar_reset()``. snnTorch and Norse keep no state between calls unless told to (snnTorch's
``init_hidden=True``, which the model must then reset itself).
"""

from dataclasses import dataclass, fields, replace

from simlidar.errors import ConfigError
from simlidar.resources import check_memory
from simlidar.settings import Choice, Range, check, setting

LOGITS, FIRST_SPIKE_TIMES, STEPPED_SPIKES = "logits", "first_spike_times", "stepped_spikes"
DELAYS, LATENCY, EVENTS = "delays", "latency", "events"
PADDING = -1  # every column of an "events" row that is no event
FIRST_SPIKE, SPIKE_COUNT, MEMBRANE = "first_spike", "spike_count", "membrane"
MAX_STEPS = 100_000


@dataclass(frozen=True)
class ModelSpec:
    output: str = setting(
        LOGITS, "What forward returns.", Choice((LOGITS, FIRST_SPIKE_TIMES, STEPPED_SPIKES))
    )
    encoding: str = setting(
        DELAYS, "The input forward is given.", Choice((DELAYS, LATENCY, EVENTS))
    )
    steps: int = setting(
        0,
        "Time steps of the latency and events encodings.",
        Range(0, MAX_STEPS, "an integer"),
    )
    readout: str = setting(
        FIRST_SPIKE,
        "How a stepped network's decision is read.",
        Choice((FIRST_SPIKE, SPIKE_COUNT, MEMBRANE)),
    )

    def __post_init__(self):
        check(self)
        if self.output == STEPPED_SPIKES and self.encoding == DELAYS:
            raise ConfigError(
                f"encoding={self.encoding!r} with output {self.output!r}: expected "
                f"{LATENCY!r} or {EVENTS!r} (a decision step is read against the input spikes "
                "delivered by then)"
            )
        if self.encoding in (LATENCY, EVENTS) and self.steps < 1:
            raise ConfigError(
                f"steps={self.steps}: expected at least 1 time step for the {self.encoding} "
                "encoding"
            )

    @property
    def spiking(self) -> bool:
        return self.output != LOGITS

    def table(self) -> dict:
        """The spec as a cell records it."""
        return {f.name: getattr(self, f.name) for f in fields(self)}


def spec_of(model, overrides: dict | None = None, where: str = "model") -> ModelSpec:
    """The model's declared :class:`ModelSpec` (a conventional classifier of delay images
    without one), with a recipe's ``[spec]`` table over it; ConfigError starting with
    ``where`` for a bad declaration or key."""
    declared = getattr(model, "simlidar_spec", ModelSpec())
    if not isinstance(declared, ModelSpec):
        raise ConfigError(
            f"{where}: simlidar_spec: expected a simlidar.models.protocol.ModelSpec, "
            f"got {type(declared).__name__}"
        )
    if not overrides:
        return declared
    names = [f.name for f in fields(ModelSpec)]
    unknown = sorted(set(overrides) - set(names))
    if unknown:
        raise ConfigError(f"{where}: unknown key 'spec.{unknown[0]}': expected one of {names}")
    try:
        return replace(declared, **overrides)
    except ConfigError as exc:
        raise ConfigError(f"{where}: [spec] {exc}") from None


# stateful modules of outside libraries, known by a base class's module and name (no import of
# the library), and the method that puts them back at rest
STATEFUL_BASES = {("spikingjelly", "MemoryModule"): "reset"}


def _reset_method(module) -> str | None:
    if callable(getattr(module, "simlidar_reset", None)):
        return "simlidar_reset"
    for c in type(module).__mro__:
        method = STATEFUL_BASES.get((c.__module__.split(".")[0], c.__name__))
        if method is not None:
            return method
    return None


def stateful_modules(model) -> list:
    """(module, name of its reset method) of each stateful module of ``model``, itself included."""
    found = [(m, _reset_method(m)) for m in model.modules()]
    return [(m, method) for m, method in found if method is not None]


def reset_state(model, *_) -> None:
    """Put every stateful module of ``model`` back at rest (SpikingJelly's membrane potentials,
    say): a forward pre-hook, so that each forward call starts from a new batch's rest state."""
    for module, method in stateful_modules(model):
        getattr(module, method)()


def encode(delays, spec: ModelSpec, silent_from: float):
    """The input a model wants, from a batch of delays (B, 1, H, W) (see the module's table).

    silent_from : delays at or above this are no return, hence no spike (the profile's rule,
        :func:`simlidar.dataset.loaders.spike_threshold`; inf: every pixel spikes)
    """
    if spec.encoding == DELAYS:
        return delays
    import torch

    step, fires = _steps(delays, spec.steps, silent_from)
    if spec.encoding == EVENTS:
        return _events(step, fires, delays.shape[-1], delays.dtype)
    check_memory(
        spec.steps * delays.numel() * delays.element_size(),
        f"[spec] steps = {spec.steps}: the latency encoding of a batch {tuple(delays.shape)}",
    )
    spikes = torch.zeros((spec.steps, *delays.shape), dtype=delays.dtype, device=delays.device)
    spikes.scatter_(0, step[None], fires[None].to(delays.dtype))
    return spikes


def arrivals(delays, steps: int, silent_from: float):
    """Input spikes of each sample arrived by the end of each step, (T, B) int64: what the
    "latency" and "events" encodings deliver up to a step."""
    import torch

    step, fires = _steps(delays, steps, silent_from)
    step = step.reshape(len(delays), -1)
    per_step = torch.zeros((len(delays), steps), dtype=torch.int64, device=delays.device)
    per_step.scatter_add_(1, step, fires.reshape(len(delays), -1).to(torch.int64))
    return per_step.cumsum(1).T


def _steps(delays, steps: int, silent_from: float):
    """(each pixel's spike step, whether it spikes), both shaped as ``delays``."""
    import torch

    step = torch.clamp((delays * steps).floor().long(), 0, steps - 1)
    return step, delays < silent_from


def _events(step, fires, width: int, dtype):
    """The "events" encoding of spike steps and spiking pixels (B, 1, H, W)."""
    import torch

    batch = len(step)
    step, fires = step.reshape(batch, -1), fires.reshape(batch, -1)
    key = torch.where(fires, step, step.max() + 1 if step.numel() else 0)
    order = torch.sort(key, dim=1, stable=True).indices  # by step, then pixel index
    pixel = order.to(dtype)
    rows = torch.stack(
        [
            pixel % width,
            torch.div(pixel, width, rounding_mode="floor"),
            step.gather(1, order).to(dtype),
            torch.zeros_like(pixel),
        ],
        dim=2,
    )
    return torch.where(fires.gather(1, order)[..., None], rows, torch.full_like(rows, PADDING))


def tonic_events(events) -> list:
    """Each sample of an "events" batch (B, E, 4) as a Tonic event array
    (:data:`simlidar.dataset.loaders.EVENT_DTYPE`: x, y, t in steps, p), padding dropped."""
    import numpy as np

    from simlidar.dataset.loaders import EVENT_DTYPE

    rows = events.detach().cpu().numpy().astype(np.int64)
    samples = []
    for sample in rows:
        sample = sample[sample[:, 3] != PADDING]
        out = np.zeros(len(sample), EVENT_DTYPE)
        for i, name in enumerate(EVENT_DTYPE.names):
            out[name] = sample[:, i]
        samples.append(out)
    return samples


def split_output(out, spec: ModelSpec):
    """(spikes, membrane or None) of a stepped network's output; the output itself otherwise."""
    if spec.output != STEPPED_SPIKES:
        return out, None
    if isinstance(out, tuple | list):
        return out[0], (out[1] if len(out) > 1 else None)
    return out, None


def readout(out, spec: ModelSpec):
    """(predicted class (B,) with -1 for no decision, decision step (B,) or None) of a batch's
    output; the step is 0-based, -1 where undecided, and None for non-stepped outputs."""
    import torch

    if spec.output == LOGITS:
        return out.argmax(1), None
    if spec.output == FIRST_SPIKE_TIMES:
        from simlidar.models import ttfs

        return ttfs.predict(out), None
    spikes, membrane = split_output(out, spec)
    steps, batch, _ = spikes.shape
    rows = torch.arange(batch, device=spikes.device)
    if spec.readout == FIRST_SPIKE:
        any_step = (spikes > 0).any(2)  # (T, B)
        decided = any_step.any(0)
        step = torch.where(decided, any_step.to(torch.int8).argmax(0), -1)
        at = step.clamp(min=0)
        winners = spikes[at, rows] > 0  # (B, C): the neurons spiking at the decision step
        if membrane is not None:
            winners = _highest(winners, membrane[at, rows])
        return torch.where(decided, _first(winners), -1), step
    last = torch.full((batch,), steps - 1, device=spikes.device)
    if spec.readout == MEMBRANE:
        if membrane is None:
            raise ConfigError("readout 'membrane': expected the model to return (spikes, membrane)")
        return _first(_highest(torch.ones_like(membrane[-1], dtype=torch.bool), membrane[-1])), last
    counts = spikes.sum(0)  # (B, C)
    winners = counts == counts.max(1, keepdim=True).values
    if membrane is not None:
        winners = _highest(winners, membrane[-1])
    silent = (counts.sum(1) == 0) & (membrane is None)
    return torch.where(silent, -1, _first(winners)), torch.where(silent, -1, last)


def _highest(candidates, values):
    """Of the ``candidates`` (B, C) of each row, those with the highest ``values`` (B, C)."""
    import torch

    masked = torch.where(candidates, values, -torch.inf)
    return candidates & (masked == masked.max(1, keepdim=True).values)


def _first(winners):
    """The lowest index among each row's ``winners`` (B, C) (0 where a row has none)."""
    import torch

    return winners.to(torch.int8).argmax(1)


def class_scores(out, spec: ModelSpec, logits: str = "z", scale: float = 1.0):
    """Logits for the cross-entropy loss of any model's output (B, classes): logits as they
    are; first-spike times as -z (``logits`` "z", the paper's) or -ln z = -t ("time"), times
    ``scale``; a stepped network's spike counts over its steps (snnTorch's count loss), or its
    last membrane potential for the "membrane" readout."""
    if spec.output == LOGITS:
        return out
    if spec.output == FIRST_SPIKE_TIMES:
        import torch

        from simlidar.models import ttfs

        return scale * ttfs.output_logits(out if logits == "z" else torch.log(out))
    spikes, membrane = split_output(out, spec)
    if spec.readout == MEMBRANE:
        if membrane is None:
            raise ConfigError("readout 'membrane': expected the model to return (spikes, membrane)")
        return membrane[-1]
    return spikes.sum(0)
