"""What a model must show before it trains: built for the data, an output of the kind and shape
it declares, finite outputs and weights, and a build and first forward within the time cap."""

import math
import signal
import threading
from contextlib import contextmanager

import torch

from simlidar.errors import ConfigError, TrainingError, raised
from simlidar.models.protocol import (
    FIRST_SPIKE_TIMES,
    STEPPED_SPIKES,
    ModelSpec,
    encode,
    spec_of,
    split_output,
)
from simlidar.models.registry import build_model


def prepared_model(
    recipe: dict,
    x: torch.Tensor,
    classes: int,
    generator: torch.Generator,
    device: torch.device,
    silent_from: float,
):
    """(model, spec): the recipe's model built for inputs like ``x`` (N, 1, H, W) and
    ``classes``, on ``device``, its declaration read and its output on two samples of ``x``
    checked (:func:`check_output`); a ConfigError naming the builder for a model with nothing
    to train and no ``simlidar_fit``. What ``train`` does before its first epoch, and what a
    suite checks of every model before it writes anything (:func:`probe_model`).

    recipe : a loaded recipe (:func:`simlidar.models.registry.load_recipe`)
    generator : the torch.Generator the builder draws the initial weights from
    silent_from : the data's no-return threshold (delays at or above it are no spike;
        :func:`simlidar.dataset.loaders.spike_threshold`): set on a spiking model (or one with
        a ``silent_from`` attribute) and used to encode the checked samples
    """
    where = f"recipe {recipe.get('name', '?')}"
    if "stream" in recipe:
        raise ConfigError(
            f"{where}: a stream network (its [stream] table); expected a window model here: run "
            "it on a stream dataset (simlidar bench --suite stream, benchmark/stream_bench.py)"
        )
    model = build_model(recipe, tuple(x.shape[1:]), classes, generator)
    spec = spec_of(model, recipe.get("spec"), where)
    if hasattr(model, "silent_from") or spec.spiking:
        model.silent_from = silent_from
    model.to(device)
    builder = f"{where}: builder {recipe['model']!r}"
    check_output(model, spec, x, classes, builder, silent_from)
    if not hasattr(model, "simlidar_fit") and not any(p.requires_grad for p in model.parameters()):
        raise ConfigError(
            f"{builder}: the model has no trainable parameters; expected an nn.Module with "
            "parameters to train, or a simlidar_fit method (a model trained elsewhere)"
        )
    return model, spec


def probe_model(recipe: dict, shape: tuple[int, int], classes: int, max_seconds: float) -> None:
    """Build the recipe's model for samples of ``shape`` (H, W) and ``classes`` and check its
    output on two random delay images (:func:`prepared_model`), within ``max_seconds``: a suite
    refuses a model this way before it writes anything."""
    generator = torch.Generator().manual_seed(0)
    x = torch.rand((2, 1, *shape), generator=generator)
    where = f"recipe {recipe.get('name', '?')}: building the model and its first forward"
    # a builder that draws from torch's global generator draws the same after the probe
    with time_limit(max_seconds, where), torch.random.fork_rng(devices=[]):
        prepared_model(recipe, x, classes, generator, torch.device("cpu"), 1.0)


# the least time a model is given to build and run its first batch of 2 under a time cap:
# a cap of 0 s means "one epoch" (the cap is checked after each), never "no time to build"
PROBE_FLOOR_S = 30.0


@contextmanager
def time_limit(cap: float, what: str):
    """Raise a ConfigError naming ``what`` once the time cap ``cap`` (at least
    :data:`PROBE_FLOOR_S`) has passed inside: a builder or a first forward that sleeps or
    loops, which the per-epoch time cap never sees. Needs the main thread's signals (SIGALRM);
    elsewhere, and without a finite cap, it does nothing. A forward stuck inside one long C
    call is stopped when that call returns."""
    if not math.isfinite(cap) or threading.current_thread() is not threading.main_thread():
        yield
        return
    seconds = max(cap, PROBE_FLOOR_S)

    def expire(_signum, _frame):
        raise ConfigError(
            f"{what}: still running after the time cap of {seconds:g} s; expected a model "
            "that builds and runs a batch of 2 within --max-seconds"
        )

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def check_output(
    model, spec: ModelSpec, x: torch.Tensor, classes: int, where: str, silent_from: float = 1.0
) -> None:
    """Run the model on two samples of ``x`` (N, 1, H, W) delays, encoded with the data's
    no-return threshold ``silent_from``, and refuse, in one line naming ``where``, an output of
    the wrong kind or shape for what it declares (before any training).

    spec : the model's declaration (:func:`simlidar.models.protocol.spec_of`): the encoding
        it is fed, its output's kind and, for stepped spikes, its steps
    classes : the class count, the output's last axis
    """
    device = next(iter(model.parameters()), torch.empty(0)).device
    was_training = model.training
    model.eval()
    try:
        with torch.no_grad():
            out = model(encode(x[:2].to(device), spec, silent_from))
    except ConfigError:  # the time cap (time_limit)
        raise
    except (Exception, SystemExit) as exc:
        raise ConfigError(
            f"{where}: the model's forward on a batch of 2 {spec.encoding} inputs raised "
            f"{raised(exc)}"
        ) from None
    finally:
        model.train(was_training)
    n = len(x[:2])
    if spec.output == STEPPED_SPIKES:
        spikes, membrane = split_output(out, spec)
        shapes = [
            tuple(t.shape) if isinstance(t, torch.Tensor) else None for t in (spikes, membrane)
        ]
        good = (
            shapes[0] is not None
            and shapes[0] == (spec.steps, n, classes)
            and (membrane is None or shapes[1] == shapes[0])
        )
        expected = (
            f"output spikes ({spec.steps} steps, {n}, {classes}), or a tuple (spikes, membrane) "
            "of those"
        )
        got = shapes if membrane is not None else shapes[0]
    else:
        good = isinstance(out, torch.Tensor) and tuple(out.shape) == (n, classes)
        expected = f"{spec.output} ({n}, {classes})"
        got = tuple(out.shape) if isinstance(out, torch.Tensor) else type(out).__name__
    if not good:
        raise ConfigError(
            f"{where}: the model's output for a batch of {n} is {got}; expected {expected} "
            f"(it declares output {spec.output!r})"
        )
    tensors = [t for t in (out if isinstance(out, tuple | list) else (out,)) if t is not None]
    integer = next((t.dtype for t in tensors if not t.is_floating_point()), None)
    if integer is not None:  # cross-entropy and the readouts need floating-point scores
        raise ConfigError(
            f"{where}: the model's output is {integer}; expected a floating-point "
            f"{spec.output} tensor (a float32 or float64 dtype)"
        )
    check_finite(out, spec, f"{where}: before training")


def check_weights(model: torch.nn.Module, when: str) -> None:
    """Refuse a model whose parameters hold NaN or an infinity (a TrainingError naming
    ``when``): weights a step made non-finite score every sample as one class."""
    for name, p in model.named_parameters():
        if not torch.isfinite(p).all():
            raise TrainingError(
                f"{when}: parameter {name!r} holds {p[~torch.isfinite(p)][0].item()}; "
                "expected finite weights (the training diverged): nothing is kept"
            )


def check_finite(out, spec: ModelSpec, when: str) -> None:
    """Refuse a model's output (a tensor, or a tuple of them) holding NaN, or an infinity where
    the output kind has none: only first-spike times say "no spike" with +inf. A TrainingError
    naming ``when`` (the epoch): a NaN output would score as class 0 and be published."""
    for tensor in out if isinstance(out, tuple | list) else (out,):
        if not isinstance(tensor, torch.Tensor) or not tensor.is_floating_point():
            continue  # the kind and shape are check_output's
        allowed = tensor == torch.inf if spec.output == FIRST_SPIKE_TIMES else False
        bad = ~(torch.isfinite(tensor) | allowed)
        if bad.any():
            value = tensor[bad][0].item()
            raise TrainingError(
                f"{when}: the model's output holds {value} ({int(bad.sum())} of "
                f"{tensor.numel()} values); expected finite {spec.output} (a model that "
                "diverged, or a recipe's setting that overflows): nothing is kept"
            )
