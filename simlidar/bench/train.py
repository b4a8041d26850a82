"""Seeded training of any registered model on a dataset in the simlidar schema.

Model selection (docs/benchmark.md, Training and model selection): a stratified validation
split is carved out of the train split (``[training] validation``, a fraction; seeded by the
training seed), the weights of the epoch with the best validation accuracy are kept (ties: the
lower validation loss), training stops once ``patience`` epochs brought no improvement (the
defaults: :class:`~simlidar.models.training.TrainingConfig`), and the test split is read once,
at the end. A learning rate schedule that anneals to 0 (``cosine``) defines its own end: such
a run keeps its last epoch and runs every epoch, and the validation split only reports
(choosing among the near-equal epochs of an annealed run picks the luckiest draw of a small
validation split, not a better model).
"""

import copy
import io
import math
import os
import signal
import tempfile
import threading
import time
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F

from simlidar.atomic import write_file
from simlidar.dataset.loaders import load_split, spike_threshold, split_info
from simlidar.errors import ConfigError, DatasetError, TrainingError, raised
from simlidar.generator.pulses import noisy_delays, scan_delays
from simlidar.models.protocol import (
    FIRST_SPIKE_TIMES,
    STEPPED_SPIKES,
    ModelSpec,
    class_scores,
    encode,
    readout,
    spec_of,
    split_output,
)
from simlidar.models.registry import build_model
from simlidar.models.training import TrainingConfig

STOPS = ("plateau", "epochs", "time", "own-fit")  # why training stopped (TrainResult.stopped)
SELECTION = "best-validation-accuracy-then-loss/v1"  # the rule's name, recorded by every cell
ANNEALED = "last-epoch-of-annealed-schedule/v1"  # the rule of a schedule that anneals to 0


def selection_rule(training: TrainingConfig) -> str:
    """The name of the rule that picks a run's kept epoch: the best validation epoch, or the
    last one where the learning rate schedule anneals to 0 (``cosine``)."""
    return ANNEALED if training.lr_schedule == "cosine" else SELECTION


@dataclass(kw_only=True)
class TrainResult:
    model: torch.nn.Module  # with the weights of ``best_epoch``
    recipe: dict
    test_accuracy: float
    seconds: float
    epochs: int  # epochs run
    history: list[dict] = field(default_factory=list)  # per epoch: loss, lr, val_*, seconds
    best_epoch: int = 0  # 0-based epoch whose weights were kept (the last without validation)
    stopped: str = "epochs"  # one of STOPS
    validation_size: int = 0
    test_predictions: np.ndarray | None = None  # predicted class of every test sample (-1: none)
    rule: str = SELECTION  # the selection rule (selection_rule) that picked ``best_epoch``
    epoch_cap: int = 0  # the epochs it was given (``epochs`` is how many it ran)
    spec: ModelSpec = field(default_factory=ModelSpec)  # what the model declared (protocol)
    silent_from: float = 1.0  # the data's no-return threshold its inputs were encoded with
    device: str = "cpu"  # where it trained

    def selection(self) -> dict:
        """What a benchmark cell records about the selection (docs/benchmark.md)."""
        return {
            "best_epoch": self.best_epoch,
            "epochs_run": self.epochs,
            "stopped": self.stopped,
            "validation_size": self.validation_size,
            "validation_curve": [h.get("val_accuracy") for h in self.history],
        }


def make_optimizer(params, training: TrainingConfig):
    if training.optimizer == "adam":
        return torch.optim.Adam(params, lr=training.lr)
    return torch.optim.SGD(params, lr=training.lr, momentum=training.momentum)


def is_spiking(model: torch.nn.Module) -> bool:
    """Whether a model's outputs are spikes (first-spike times or spikes over time steps)
    rather than logits: what it declares (:func:`simlidar.models.protocol.spec_of`)."""
    return spec_of(model).spiking


def batch_loss(
    model: torch.nn.Module,
    x: torch.Tensor,
    y: torch.Tensor,
    training: TrainingConfig,
    spec: ModelSpec | None = None,
):
    """(cross-entropy, cross-entropy plus the recipe's penalties) on one encoded batch: the
    model's own ``simlidar_loss`` where it has one (simlidar's spiking networks add their
    penalties there), else the cross-entropy of its class scores."""
    spec = spec or spec_of(model)
    own = getattr(model, "simlidar_loss", None)
    if own is not None:
        loss, total = own(x, y, training)
    else:
        scores = class_scores(model(x), spec, training.logits, training.logit_scale)
        loss = total = F.cross_entropy(scores, y)
    total = total + training.l2 * sum((p**2).sum() for p in model.parameters())
    return loss, total


def validation_count(n: int, fraction: float, name: str) -> int:
    """The rows :func:`validation_split` holds out of a class ``name`` of ``n`` training
    samples, ``max(1, round(fraction * n))``; a ConfigError when none would be left to train
    on. Needs the counts only: a suite's generated datasets are checked from their sizes."""
    take = max(1, int(np.floor(fraction * n + 0.5)))
    if take >= n:
        raise ConfigError(
            f"validation fraction {fraction} leaves class {name!r} ({n} training "
            "sample(s)) with no sample to train on; expected a fraction that keeps at least "
            "one sample of every class for training and one for validation, or 0 (no "
            "validation; on the command line --validation 0)"
        )
    return take


def validation_split(
    labels: np.ndarray, fraction: float, seed: int, class_names
) -> tuple[np.ndarray, np.ndarray]:
    """(training rows, validation rows) of a train split, stratified by class.

    From each class with n training samples, ``max(1, round(fraction * n))`` rows are drawn
    without replacement for validation (a generator seeded by ``seed``: the same rows for the
    same seed); ``fraction`` 0 keeps every row for training. A ConfigError names a class that
    would be left without a training sample.
    """
    rows = np.arange(len(labels))
    if fraction == 0:
        return rows, rows[:0]
    rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence(seed, spawn_key=(11,))))
    held = []
    for label, name in enumerate(class_names):
        mine = rows[labels == label]
        if len(mine) == 0:
            continue
        held.append(rng.permutation(mine)[: validation_count(len(mine), fraction, name)])
    validation = np.sort(np.concatenate(held)) if held else rows[:0]
    return np.setdiff1d(rows, validation), validation


def fresh_noise(dataset, attrs: dict, seed: int, rows: np.ndarray):
    """``noise_augment``: a function drawing the train split's noise anew (same level, same
    profile rule, from ``clean_delays``) for each epoch, (len(rows), H, W) float32 delays: the
    paper's "adding noise randomly" as augmentation rather than one fixed draw per sample, for
    the training ``rows`` (the validation rows keep the file's draw, like the test split).
    Seeded by the training seed. The early-information bound draws the same way. Under scan
    timing the noise is drawn on each pulse's time of flight, as the generator draws it, and the
    draw made arrival times again (before issue 42 it was added to the arrival times: a jitter
    of ``noise`` times the whole 9.5 ms window)."""
    if "source" in attrs or "noise" not in attrs:
        raise ConfigError(
            f"{dataset}: training option noise_augment: expected a generated dataset "
            "(clean_delays and a noise level), got converted data"
        )
    clean = load_split(dataset, "train", field="clean_delays")[0][rows]
    level = float(attrs["noise"])
    missing = float(attrs.get("no_return_delay", 1.0))
    noise_on = attrs.get("noise_on", "returns")
    rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence(seed, spawn_key=(7,))))
    timed = scan_clock(dataset, attrs, rows)
    if timed is not None:  # the noise is on the time of flight, then the sweep's clock
        clean = flash_delays(clean, *timed)

    def draw() -> np.ndarray:
        u = rng.random(clean.shape, dtype=np.float32)
        noisy = noisy_delays(clean, level, u, missing, noise_on)
        return noisy if timed is None else scan_delays(noisy, *timed)

    return draw


def scan_clock(dataset, attrs: dict, rows: np.ndarray):
    """A scan-timed train split's (emission_ns of ``rows``, tof_max_ns, window_ns), the
    arguments of :func:`simlidar.generator.pulses.scan_delays`; None under flash timing."""
    if attrs.get("timing") != "scan":
        return None
    emission = load_split(dataset, "train", field="emission_ns")[0][rows]
    return emission, float(attrs["tof_max_ns"]), float(attrs["delay_unit_ns"])


def flash_delays(arrival: np.ndarray, emission_ns, tof_max_ns: float, window_ns: float):
    """Scan-timed delays -> the flash delays they were made from (the inverse of
    :func:`simlidar.generator.pulses.scan_delays`, to within the float32 rounding of an
    arrival time: 4e-4 of ``tof_max_ns`` for a 9.5 ms window); 1.0 (no return) stays 1.0."""
    tof = (arrival.astype(np.float64) * window_ns - emission_ns) / tof_max_ns
    below_one = np.nextafter(np.float32(1.0), np.float32(0.0))
    return np.where(arrival < 1.0, np.clip(tof, 0.0, below_one), 1.0).astype(np.float32)


def _batches(
    model,
    x: torch.Tensor,
    spec: ModelSpec,
    silent_from: float,
    batch: int,
    exact: bool = False,
    when: str = "scoring",
):
    """Each batch of ``x`` (N, 1, H, W) encoded for the model on its device, and its output
    (:func:`check_finite`: a TrainingError naming ``when`` for NaN, or an infinity that is no
    "no spike").

    exact : a model that the event-driven evaluator runs (``event_driven``) is run on float64
        input spikes: the exact spike times of its float32 weights, which that evaluator reads
        too (:func:`simlidar.models.decisions.decide_all`), so that a cell's ``accuracy`` and
        ``early.accuracy`` agree by construction (in float32, two output spikes less than a
        rounding step apart can swap places; training and validation stay in float32)
    """
    device = next(iter(model.parameters()), torch.empty(0)).device
    model.eval()
    if exact and getattr(model, "event_driven", False):
        x = x.double()
    with torch.no_grad():
        for i in range(0, len(x), batch):
            out = model(encode(x[i : i + batch].to(device), spec, silent_from))
            check_finite(out, spec, when)
            yield i, out


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


def predictions(
    model: torch.nn.Module,
    x: torch.Tensor,
    batch: int = 500,
    spec: ModelSpec | None = None,
    silent_from: float | None = None,
) -> torch.Tensor:
    """Predicted classes of any model, in batches, on the CPU (-1: no decision); simlidar's
    event-driven networks in float64 (:func:`_batches`, ``exact``).

    x : (N, 1, H, W) delays, encoded as the model wants (``spec``; default: what it declares)
    silent_from : the data's no-return threshold (default: the model's, else 1.0)
    """
    spec = spec or spec_of(model)
    silent_from = getattr(model, "silent_from", 1.0) if silent_from is None else silent_from
    runs = _batches(model, x, spec, silent_from, batch, exact=True, when="scoring the test split")
    outs = [readout(out, spec)[0].cpu() for _, out in runs]
    return torch.cat(outs) if outs else torch.zeros(0, dtype=torch.long)


def evaluate(
    model: torch.nn.Module,
    x: torch.Tensor,
    y: torch.Tensor,
    training: TrainingConfig,
    batch: int = 500,
    spec: ModelSpec | None = None,
    silent_from: float = 1.0,
    when: str = "validation",
) -> tuple[float, float | None]:
    """(accuracy, mean cross-entropy with the recipe's logits) on ``x``, in eval mode; the loss
    is None where it is not finite (a spiking network whose correct output never fired).
    ``when``: what a TrainingError for a NaN output names (:func:`check_finite`)."""
    spec = spec or spec_of(model)
    correct, loss = 0, 0.0
    for i, out in _batches(model, x, spec, silent_from, batch, when=when):
        target = y[i : i + batch].to(_first_tensor(out).device)
        correct += int((readout(out, spec)[0] == target).sum())
        scores = class_scores(out, spec, training.logits, training.logit_scale)
        loss += F.cross_entropy(scores, target, reduction="sum").item()
    loss /= len(x)
    return correct / len(x), (loss if np.isfinite(loss) else None)


def _first_tensor(out) -> torch.Tensor:
    return out[0] if isinstance(out, tuple | list) else out


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
    suite checks of every model before it writes anything (:func:`probe_model`)."""
    where = f"recipe {recipe.get('name', '?')}"
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
    the wrong kind or shape for what it declares (before any training)."""
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


def better_score(
    score: tuple[float, float | None], best: tuple[float, float | None] | None
) -> bool:
    """A higher validation accuracy, or the same with a lower (finite) validation loss."""
    if best is None or score[0] != best[0]:
        return best is None or score[0] > best[0]
    return score[1] is not None and (best[1] is None or score[1] < best[1])


def train(
    recipe: dict,
    dataset: str | Path,
    seed: int = 0,
    epochs: int | None = None,
    max_seconds: float | None = None,
    progress: bool = True,
    device: torch.device | str = "cpu",
) -> TrainResult:
    """Train the recipe's model on ``dataset``'s train split (less the validation rows), keep
    the epoch with the best validation score, and score it once on the test split.

    The model is fed the encoding it declares (:mod:`simlidar.models.protocol`) on ``device``;
    one with its own ``simlidar_fit`` trains itself and is then scored the same way.
    Deterministic for a given seed, recipe, dataset, device and thread count (one
    torch.Generator drives the initial weights and the batch order; the validation rows are
    drawn from the seed too).
    """
    from tqdm import tqdm

    where = f"recipe {recipe.get('name', '?')}"
    training = TrainingConfig.from_table(recipe["training"], where).over(
        epochs=epochs, max_seconds=max_seconds
    )
    x_all, y_all = (torch.from_numpy(a) for a in load_split(dataset, "train"))
    attrs = split_info(dataset, "train").attrs
    classes = len(attrs["class_names"])
    try:
        rows, held = validation_split(
            y_all.numpy(),
            training.validation,
            seed,
            [str(n) for n in attrs["class_names"]],
        )
    except ConfigError as exc:
        raise ConfigError(f"{where}: key 'training.validation': {exc}") from None
    x_all = x_all[:, None]  # (N, 1, H, W)
    x_train, y_train = x_all[rows], y_all[rows]
    x_val, y_val = x_all[held], y_all[held]
    patience = training.patience
    annealed = selection_rule(training) == ANNEALED
    generator = torch.Generator().manual_seed(seed)
    silent_from = spike_threshold(attrs)  # the encoding follows the data's profile
    device = torch.device(device)
    with time_limit(training.max_seconds, f"{where}: building the model and its first forward"):
        model, spec = prepared_model(recipe, x_train, classes, generator, device, silent_from)
    if hasattr(model, "simlidar_fit"):
        parts = (x_train, y_train, x_val, y_val, silent_from)
        return _own_fit(model, recipe, spec, dataset, training, generator, device, parts)
    draw = None
    if training.noise_augment:
        draw = fresh_noise(dataset, attrs, seed, rows)
    optimizer = make_optimizer(model.parameters(), training)
    epochs, budget, batch = training.epochs, training.max_seconds, training.batch_size
    schedule = None
    if training.lr_schedule == "cosine":
        schedule = torch.optim.lr_scheduler.CosineAnnealingLR(optimizer, max(epochs, 1))
    start = time.perf_counter()
    history = []
    best, best_epoch, best_state, stopped = None, 0, None, "epochs"
    bar = tqdm(range(epochs), desc=f"train {recipe.get('name', '')}", disable=not progress)
    for epoch in bar:
        model.train()
        if draw is not None:
            x_train = torch.from_numpy(draw())[:, None]
        order = torch.randperm(len(y_train), generator=generator)
        losses = []
        # a scheduled early-decision term is off before its epoch
        now = training if epoch >= training.early_start else replace(training, early_penalty=0.0)
        for i in range(0, len(order), batch):
            rows = order[i : i + batch]
            x = encode(x_train[rows].to(device), spec, silent_from)
            loss, total = batch_loss(model, x, y_train[rows].to(device), now, spec)
            if not torch.isfinite(total):
                raise TrainingError(
                    f"{where}: epoch {epoch}: the training loss is {total.item()}; expected a "
                    "finite loss (a model whose output is NaN or infinite, or a recipe's "
                    "setting that overflows): nothing is kept"
                )
            optimizer.zero_grad()
            total.backward()
            if training.clip_grad_norm:
                torch.nn.utils.clip_grad_norm_(model.parameters(), training.clip_grad_norm)
            optimizer.step()
            losses.append(loss.item())
        lr = optimizer.param_groups[0]["lr"]  # the rate this epoch trained with
        if schedule is not None:
            schedule.step()
        record = {"epoch": epoch, "loss": float(np.mean(losses)), "lr": lr}
        check_weights(model, f"{where}: epoch {epoch}")
        if len(held):
            when = f"{where}: epoch {epoch}'s validation"
            score = evaluate(
                model, x_val, y_val, training, spec=spec, silent_from=silent_from, when=when
            )
            record.update(val_accuracy=score[0], val_loss=score[1])
            bar.set_postfix(loss=f"{record['loss']:.3f}", val=f"{score[0]:.3f}")
            if annealed:
                best_epoch = epoch  # the schedule's end decides: validation only reports
            elif better_score(score, best):
                best, best_epoch = score, epoch
                best_state = copy.deepcopy(model.state_dict())
        else:
            best_epoch = epoch  # no validation: the last epoch is kept
            bar.set_postfix(loss=f"{record['loss']:.3f}")
        record["seconds"] = time.perf_counter() - start
        history.append(record)
        if epoch == epochs - 1:
            break
        if len(held) and epoch - best_epoch >= patience:
            stopped = "plateau"
            break
        if record["seconds"] > budget:
            stopped = "time"
            break
    if best_state is not None:
        model.load_state_dict(best_state)
    predicted, accuracy = _score_test(model, dataset, spec, silent_from)
    return TrainResult(
        model=model,
        recipe=recipe,
        test_accuracy=accuracy,
        seconds=history[-1]["seconds"],
        epochs=len(history),
        history=history,
        best_epoch=best_epoch,
        stopped=stopped,
        validation_size=len(held),
        test_predictions=predicted.numpy(),
        rule=selection_rule(training),
        epoch_cap=epochs,
        spec=spec,
        silent_from=silent_from,
        device=str(device),
    )


def _score_test(model, dataset, spec: ModelSpec, silent_from: float):
    """(predictions, accuracy) on the test split: read once, at the end."""
    x_test, y_test = (torch.from_numpy(a) for a in load_split(dataset, "test"))
    predicted = predictions(model, x_test[:, None], spec=spec, silent_from=silent_from)
    return predicted, (predicted == y_test).float().mean().item()


OWN_FIT = "own-fit/v1"  # the selection rule of a model that trains itself (simlidar_fit)


def _own_fit(model, recipe, spec, dataset, training, generator, device, parts):
    """A model with its own ``simlidar_fit``: it trains itself on the encoded train rows (and
    may watch the validation rows); simlidar scores the validation rows (recorded) and reads
    the test split once. ``parts``: (x_train, y_train, x_val, y_val, silent_from)."""
    x_train, y_train, x_val, y_val, silent_from = parts
    start = time.perf_counter()
    model.train()
    model.simlidar_fit(
        encode(x_train.to(device), spec, silent_from),
        y_train.to(device),
        encode(x_val.to(device), spec, silent_from),
        y_val.to(device),
        generator,
    )
    record = {"epoch": 0, "loss": None, "lr": None}
    check_weights(model, f"recipe {recipe.get('name', '?')}: after simlidar_fit")
    if len(y_val):
        score = evaluate(model, x_val, y_val, training, spec=spec, silent_from=silent_from)
        record.update(val_accuracy=score[0], val_loss=score[1])
    record["seconds"] = time.perf_counter() - start
    predicted, accuracy = _score_test(model, dataset, spec, silent_from)
    return TrainResult(
        model=model,
        recipe=recipe,
        test_accuracy=accuracy,
        seconds=record["seconds"],
        epochs=1,
        history=[record],
        best_epoch=0,
        stopped="own-fit",
        validation_size=len(y_val),
        test_predictions=predicted.numpy(),
        rule=OWN_FIT,
        epoch_cap=1,
        spec=spec,
        silent_from=silent_from,
        device=str(device),
    )


def check_writable(folder: str | Path) -> None:
    """Create ``folder`` if needed and prove a file can be written there; a DatasetError
    naming the folder otherwise (``train`` calls it before the first epoch)."""
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix=".write-check-", dir=folder)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise DatasetError(f"--out {folder}: cannot write there ({exc.strerror})") from None


def save_checkpoint(result: TrainResult, path: str | Path) -> Path:
    """State dict plus the recipe and the run's figures; loads with ``weights_only=True``."""
    path = Path(path)
    check_writable(path.parent)
    data = {
        "state_dict": result.model.state_dict(),
        "recipe": result.recipe,
        "history": result.history,
        "silent_from": result.silent_from,
    }
    buffer = io.BytesIO()  # torch's own writer reports a full disk as "file write failed"
    torch.save(data, buffer)
    return write_file(path, lambda tmp: tmp.write_bytes(buffer.getbuffer()), what="the checkpoint")


def load_checkpoint(path: str | Path, input_shape, classes):
    """Rebuild a model from a checkpoint written by :func:`save_checkpoint` (on the CPU)."""
    data = torch.load(path, weights_only=True, map_location="cpu")
    model = build_model(data["recipe"], input_shape, classes)
    model.load_state_dict(data["state_dict"])
    if hasattr(model, "silent_from") or is_spiking(model):
        model.silent_from = float(data.get("silent_from", 1.0))  # older checkpoints: 1.0
    return model, data
