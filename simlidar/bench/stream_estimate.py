"""The early-information estimate in the stream (docs/streams.md, "What the data allow"): how
right a decision can be some time after an object's first return, from what the sensor knows
by then, before any network.

At a time T of a stream, the sensor knows, for every pulse of every rotation's window: whether
it has fired (its emission at or before T) and, for a return that has arrived by T (emission
plus time of flight), its time of flight. A learner is given that as a (2, H, R W) view
(:func:`view_at`): channel 0 the time of flight over ``tof_max_ns`` of each arrived return
(1.0 elsewhere: no return, or not yet), channel 1 whether the pulse has fired (a pulse fired
without a return by T has none: its return would have come within 667 ns).

**Not told when the object came.** A learner trained on views at T = ``t_reference_us`` + d
learns where the view ends: right after the object's first return, whose place (the edge of
the window for a crossing pedestrian, its middle for an oncoming car) gives the class away
(on 200 training streams an MLP scored more 0.5 ms after the reference than 10 ms after). A
network answering as the pulses come is never told that time. So the learner is trained as a
network answers, at any time: each epoch, each training stream is seen at T = its reference
plus an offset drawn uniformly from :data:`OFFSETS_MS` (before the object and up to the latency
grid's end), and the one learner is scored on the test split's views at every delay d of the
grid. Its families and training are the static estimate's (:mod:`simlidar.bench.bound`: an MLP
and the paper's CNN, Adam, the epoch of the best validation accuracy on one draw of the offsets,
then every training stream for that many epochs, the last kept). Per d the estimate is the best
family's mean over seeds: an estimate from the learners tried, not a bound (a stronger learner
can beat it). ``benchmark/stream_estimate.py`` runs it.
"""

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from simlidar.bench.latency import US_PER_MS
from simlidar.bench.stream_task import stream_config
from simlidar.dataset.loaders import load_split, split_info
from simlidar.dataset.stream_loaders import load_stream
from simlidar.generator.pulse_streams import stream_rays

# a learner family: its model (bound.BoundConfig.model) and its view, every window so far or,
# "-lastK", the K latest windows begun by T (the one still firing last), aligned so that the
# learner finds the current window in the same place in every view
FAMILIES = ("mlp", "cnn", "mlp-last2", "cnn-last2")
# the offsets from the reference a learner is trained at, ms: from a window before the object
# (a rotation: 100 ms at 600 RPM) to past the latency grid's last delay
OFFSETS_MS = (-100.0, 110.0)


@dataclass(frozen=True)
class Known:
    """What a split's streams hold for the estimate: ToF-coded pulses, their emission and
    arrival times, labels and reference times (N streams, P = H x R W pulses)."""

    delays: np.ndarray  # (N, H, R W) float32, time of flight over tof_max_ns; 1.0 no return
    emission_us: np.ndarray  # (N, H, R W) float64
    arrival_us: np.ndarray  # (N, H, R W) float64, inf: no return
    labels: np.ndarray  # (N,)
    reference_us: np.ndarray  # (N,)
    classes: int
    width: int  # W, a window's columns


def known(dataset: str | Path, split: str) -> Known:
    """A stream split's pulses with their times (the emissions from the stored phase)."""
    attrs = split_info(dataset, split).attrs
    config = stream_config(attrs)
    delays, labels = load_split(dataset, split)
    stream = load_stream(dataset, split)
    _, _, emission_ns, _ = stream_rays(config, stream.samples["phase"])
    events = stream.events  # the arrivals as stored (the delays are float32 of them)
    arrival = np.full(delays.shape, np.inf)
    sample = np.repeat(np.arange(len(labels)), events.count)
    column = np.round(events.t_us / config.rotation_us).astype(np.int64) * config.width + events.x
    arrival[sample, events.y, column] = events.t_us
    return Known(delays, emission_ns * 1e-3, arrival, labels, stream.samples["t_reference_us"],
                 len(attrs["class_names"]), config.width)  # fmt: skip


def view_at(data: Known, delay_ms, last: int | None = None) -> np.ndarray:
    """The (N, 2, P) view of what each stream's sensor knows ``delay_ms`` (a number, or (N,)
    one a stream) after its reference time (module docstring); with ``last``, of its ``last``
    latest windows begun by then alone, the current one last (P = H x last W; a window before
    the first is nothing: no return, not fired)."""
    at = (data.reference_us + np.asarray(delay_ms) * US_PER_MS)[:, None, None]
    arrived = data.arrival_us <= at
    view = np.stack([np.where(arrived, data.delays, 1.0), data.emission_us <= at], axis=1)
    if last is not None:
        n, _, height, columns = view.shape
        width = data.width
        begun = view[:, 1].reshape(n, height, -1, width).any(axis=(1, 3)).sum(axis=1)  # (N,)
        padded = np.concatenate([np.zeros((n, 2, height, last * width)), view], axis=3)
        padded[:, 0, :, : last * width] = 1.0
        first = begun[:, None] * width + np.arange(last * width)[None, :]  # in padded columns
        view = np.take_along_axis(padded, first[:, None, None, :].repeat(2, 1).repeat(height, 2), 3)
    return view.reshape(len(view), 2, -1).astype(np.float32)


def family_parts(family: str) -> tuple[str, int | None]:
    """A family's model and the windows its view keeps (None: all): "cnn-last2" -> ("cnn", 2)."""
    model, _, last = family.partition("-last")
    return model, int(last) if last else None


def any_time(data: Known, rng: np.random.Generator, last: int | None = None):
    """A function drawing the training view anew (one call an epoch): each stream at its
    reference plus an offset uniform in :data:`OFFSETS_MS` (``last``: :func:`view_at`'s)."""

    def draw() -> np.ndarray:
        return view_at(data, rng.uniform(*OFFSETS_MS, size=len(data.labels)), last)

    return draw
