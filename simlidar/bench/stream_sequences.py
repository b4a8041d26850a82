"""Stream networks on a stream dataset (docs/streams.md, "Sequence networks"): a network that
reads a whole stream step by step (:mod:`simlidar.models.stream_nets`: a recipe with a
``[stream]`` table) trained and scored on the sensor's clock.

* **Steps.** ``rotations``: one step a rotation, its window's times of flight, answered when the
  rotation's frame is complete (:func:`simlidar.bench.stream_task.stream_views`' frame clock,
  cut at the rear); ``bins``: one step every ``bin_ms`` of sensor time from the stream's first
  firing, the events of the bin (channel 0) and their nearness, 1 - the time of flight over
  ``tof_max_ns`` (channel 1), answered at the bin's end (an event arrives in the bin of its
  arrival time, so an answer never comes before the events it was made from).
* **What a network learns from.** Each training stream is cut to a crop that starts u steps
  before the step holding its reference (u drawn uniformly from 0 to :data:`BEFORE_MS` of
  steps, or fewer where a split's earliest reference is sooner) and runs :data:`AFTER_MS` on (a
  rotation network: to the stream's end), from rest; the loss is the cross-entropy of the
  stream's class at every step of the crop from the reference's on, as the frame-based
  networks learn from the windows from the reference's on. The crop keeps the time since the
  stream began from the network: the reference comes u steps into every crop, whatever the
  class, where from the stream's first firing it would come sooner for a truck than for a car
  (docs/streams.md, "What the data allow"). A network scored on the whole stream, from rest at
  its first firing, has never been told the reference's place.
* **Selection.** The validation streams (held out whole, :func:`validation_split`) run whole;
  the epoch of the best accuracy over their steps from the reference's on is kept (ties: the
  lower cross-entropy), as :func:`simlidar.bench.train.train` keeps its.
* **Answers.** On the test split, whole: the class of the highest score at every step, at its
  time; a step whose scores are all equal (nothing seen yet) gives none
  (:meth:`~simlidar.bench.latency.Answers.from_frames`).
"""

import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from simlidar.bench import latency
from simlidar.bench.selection import SELECTION, Selection, validation_split
from simlidar.bench.stream_task import stream_config, stream_views
from simlidar.bench.train import TrainingError, make_optimizer
from simlidar.dataset.loaders import split_info
from simlidar.dataset.stream_loaders import load_stream
from simlidar.errors import ConfigError
from simlidar.models.registry import build_model
from simlidar.models.stream_nets import scores_of
from simlidar.models.stream_spec import ROTATIONS, StreamSpec, stream_spec_of
from simlidar.models.training_config import TrainingConfig

BEFORE_MS = 100.0  # a crop starts up to this long before the reference's step
AFTER_MS = 150.0  # a bins crop runs this long after it (past the latency grid's 100 ms)
BATCH = 32  # streams a forward pass when a network runs whole streams


@dataclass(frozen=True)
class Sequences:
    """A stream split as a network of ``spec`` reads it (N streams of T steps)."""

    spec: StreamSpec
    labels: np.ndarray  # (N,) int64
    reference_us: np.ndarray  # (N,) float64
    step_end_us: np.ndarray  # (N, T) float64: when each step's answer is made
    reference_step: np.ndarray  # (N,) int64: the step holding the reference (the loss from it)
    span_us: float
    classes: tuple[str, ...]
    shape: tuple[int, int]  # H, W
    windows: np.ndarray | None = None  # rotations: (N, T, H, W) float32 times of flight
    events: tuple | None = None  # bins: (first row (N + 1,), step, y, x, nearness) by stream

    @property
    def steps(self) -> int:
        return self.step_end_us.shape[1]

    def batch(self, streams: np.ndarray, first: np.ndarray, length: int) -> torch.Tensor:
        """Steps first .. first + length of ``streams`` (a stream's own first step each),
        (length, B, C, H, W); steps past a stream's end are empty (no return, no event)."""
        height, width = self.shape
        steps = first[:, None] + np.arange(length)[None, :]  # (B, L)
        if self.windows is not None:
            inside = steps < self.steps
            x = np.ones((len(streams), length, height, width), np.float32)
            x[inside] = self.windows[np.repeat(streams, inside.sum(1)), steps[inside]]
            return torch.from_numpy(x.transpose(1, 0, 2, 3)[:, :, None].copy())
        starts, step, y, x_, near = self.events
        rows = np.concatenate([np.arange(starts[s], starts[s + 1]) for s in streams])
        sample = np.repeat(np.arange(len(streams)), starts[streams + 1] - starts[streams])
        at = step[rows] - first[sample]
        keep = (at >= 0) & (at < length)
        out = np.zeros((length, len(streams), 2, height, width), np.float32)
        where = (at[keep], sample[keep])
        np.add.at(out, (*where, 0, y[rows][keep], x_[rows][keep]), 1.0)
        out[(*where, 1, y[rows][keep], x_[rows][keep])] = near[rows][keep]
        return torch.from_numpy(out)


def sequences(dataset: str | Path, split: str, spec: StreamSpec) -> Sequences:
    """One split of a stream dataset read as ``spec`` says."""
    views = stream_views(dataset, split)  # labels, references, frame clock, ToF windows
    common = {
        "spec": spec,
        "labels": views.labels,
        "reference_us": views.reference_us,
        "span_us": views.span_us,
        "classes": views.classes,
        "shape": views.windows.shape[2:],
    }
    if spec.input == ROTATIONS:
        return Sequences(
            step_end_us=views.frame_end_us,
            reference_step=views.first_rotation,
            windows=views.windows,
            **common,
        )
    config = stream_config(split_info(dataset, split).attrs)
    bin_us = spec.bin_ms * latency.US_PER_MS
    steps = math.ceil((views.span_us + config.sensor.tof_max_ns * 1e-3) / bin_us)
    events = load_stream(dataset, split).events
    sample = np.repeat(np.arange(len(views.labels)), events.count)
    rotation = events.rotations(config.rotation_us)  # the windows are the split's delays
    near = 1.0 - views.windows[sample, rotation, events.y, events.x]
    starts = np.concatenate([[0], np.cumsum(events.count)]).astype(np.int64)
    step = np.floor(events.t_us / bin_us).astype(np.int64)  # the bin of the event's arrival
    ends = np.broadcast_to((np.arange(steps) + 1.0) * bin_us, (len(views.labels), steps))
    return Sequences(
        step_end_us=np.ascontiguousarray(ends),
        reference_step=np.floor(views.reference_us / bin_us).astype(np.int64),
        events=(starts, step, events.y.astype(np.int64), events.x.astype(np.int64), near),
        **common,
    )


def _scores(model, data: Sequences, streams: np.ndarray, grad: bool = False) -> torch.Tensor:
    """The network's (T, S, classes) scores on whole streams, from rest at their first firing."""
    out = []
    with torch.set_grad_enabled(grad):
        for i in range(0, len(streams), BATCH):
            part = streams[i : i + BATCH]
            x = data.batch(part, np.zeros(len(part), np.int64), data.steps)
            out.append(scores_of(model(x)))
    return torch.cat(out, dim=1)


def _after_reference(data: Sequences, streams: np.ndarray) -> torch.Tensor:
    """(T, S) bool: the steps from each stream's reference step on."""
    steps = np.arange(data.steps)[:, None] >= data.reference_step[streams][None, :]
    return torch.from_numpy(steps)


def step_score(model, data: Sequences, streams: np.ndarray) -> tuple[float, float]:
    """(accuracy, cross-entropy) over the steps from each stream's reference step on, the
    streams run whole."""
    model.eval()
    scores = _scores(model, data, streams)
    mask = _after_reference(data, streams)
    y = torch.from_numpy(data.labels[streams]).expand(data.steps, -1)
    right = (scores.argmax(-1) == y)[mask].double().mean().item()
    loss = torch.nn.functional.cross_entropy(scores[mask], y[mask]).item()
    return right, loss


def crops(data: Sequences, streams: np.ndarray, rng: np.random.Generator):
    """Each stream's crop (first step, length of the batch) and its mask of loss steps
    (module docstring)."""
    step_us = data.step_end_us[0, 1] - data.step_end_us[0, 0] if data.steps > 1 else 1.0
    if data.spec.input == ROTATIONS:
        before = 1
        after = data.steps
    else:
        before = int(round(BEFORE_MS * latency.US_PER_MS / step_us))
        after = int(round(AFTER_MS * latency.US_PER_MS / step_us))
    before = int(min(before, data.reference_step.min()))
    u = rng.integers(0, before + 1, size=len(streams))
    first = data.reference_step[streams] - u
    length = int(min(before + after, data.steps))
    at = np.arange(length)[:, None]
    mask = (at >= u[None, :]) & (first[None, :] + at < data.steps)
    return first, length, torch.from_numpy(mask)


@dataclass
class SequenceResult:
    model: torch.nn.Module
    epochs: int
    best_epoch: int
    validation: list  # per epoch: (accuracy, cross-entropy) of the validation streams
    stopped: str
    trained: np.ndarray  # the train split's streams trained on


def fit(
    recipe: dict,
    train: Sequences,
    seed: int,
    epochs: int | None = None,
    validation: float | None = None,
) -> SequenceResult:
    """Train a stream network (module docstring): Adam or SGD of the recipe's ``[training]``
    on crops of the training streams, the epoch of the best validation score kept.
    Deterministic for a seed (one torch.Generator for the weights and the stream order, one
    numpy generator for the crops).

    recipe : the network's loaded recipe (a ``[stream]`` table)
    train : the train split's Sequences
    seed : the run's seed
    epochs, validation : over the recipe's ``[training]`` epochs and validation fraction
    """
    where = f"recipe {recipe.get('name', '?')}"
    training = TrainingConfig.from_table(recipe["training"], where).over(epochs=epochs)
    fraction = training.validation if validation is None else validation
    streams, held = validation_split(train.labels, fraction, seed, list(train.classes))
    generator = torch.Generator().manual_seed(seed)
    rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence(seed, spawn_key=(60,))))
    shape = (train.spec.channels, *train.shape)
    model = build_model(recipe, shape, len(train.classes), generator)
    optimizer = make_optimizer(model.parameters(), training)
    selection = Selection(SELECTION, training.patience, len(held) > 0)
    history, stopped, start = [], "epochs", time.perf_counter()
    for epoch in range(training.epochs):
        model.train()
        order = streams[torch.randperm(len(streams), generator=generator).numpy()]
        for i in range(0, len(order), training.batch_size):
            part = order[i : i + training.batch_size]
            first, length, mask = crops(train, part, rng)
            scores = scores_of(model(train.batch(part, first, length)))
            y = torch.from_numpy(train.labels[part]).expand(length, -1)
            loss = torch.nn.functional.cross_entropy(scores[mask], y[mask])
            if training.l2:
                loss = loss + training.l2 * sum((p**2).sum() for p in model.parameters())
            if not torch.isfinite(loss):
                raise TrainingError(
                    f"{where}: epoch {epoch}: the training loss is {loss.item()}"
                    "; expected a finite loss: nothing is kept"
                )
            optimizer.zero_grad()
            loss.backward()
            if training.clip_grad_norm:
                torch.nn.utils.clip_grad_norm_(model.parameters(), training.clip_grad_norm)
            optimizer.step()
        score = step_score(model, train, held) if len(held) else None
        history.append(score)
        selection.update(epoch, score, model)
        if selection.plateau(epoch):
            stopped = "plateau"
            break
        if time.perf_counter() - start > training.max_seconds:
            stopped = "time"
            break
    selection.restore(model)
    return SequenceResult(model, len(history), selection.best_epoch, history, stopped, streams)


def sequence_answers(model, data: Sequences) -> latency.Answers:
    """A stream network's answers on a whole split: at every step the class of its highest
    score, at the step's end; none where the scores are all equal."""
    model.eval()
    scores = _scores(model, data, np.arange(len(data.labels)))  # (T, N, C)
    classes = scores.argmax(-1)
    flat = (scores.max(-1).values == scores.min(-1).values).numpy()
    classes = np.where(flat, -1, classes.numpy()).T
    return latency.Answers.from_frames(data.step_end_us, classes, len(data.classes))


def check_recipe(recipe: dict) -> StreamSpec:
    """A stream network's recipe's StreamSpec; a ConfigError for a window model's recipe."""
    spec = stream_spec_of(recipe)
    if spec is None:
        raise ConfigError(
            f"recipe {recipe.get('name', '?')}: no [stream] table; expected a stream network's "
            "recipe (gru_rotations, lif_stream, or one with [stream] input = 'rotations' or "
            "'bins')"
        )
    return spec
