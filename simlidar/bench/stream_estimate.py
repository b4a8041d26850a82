"""The early-information estimate in the stream (docs/streams.md, "What the data allow"): how
right a decision can be some time after an object's first return, from what the sensor knows
by then, before any network.

At a time T of a stream, the sensor knows, for every pulse: whether it has fired (its emission
at or before T) and, for a return that has arrived by T (emission plus time of flight), its
time of flight. A learner is given that for the K latest windows begun by T, the current one
last (:func:`view_at`), as a (2, H, K W) view: channel 0 the time of flight over
``tof_max_ns`` of each arrived return (1.0 elsewhere), channel 1 whether the pulse has fired
(a pulse fired more than 667 ns before T without a return has none; one fired in those last
667 ns may still return, and shows as fired without one).

**Not told when.** Two times would give the class away without the object's returns. The time
since the object's first return: a learner trained on views at T = ``t_reference_us`` + d
learns where the view ends, right after that return, whose place (the edge of the window for a
crossing pedestrian, its middle for an oncoming car) tells the class (on 200 training streams an
MLP scored more 0.5 ms after the reference than 10 ms after). And the time since the stream
began: which of all the windows have fired tells T, and T is tied to the class (a truck, tall
and long, comes into view sooner than a car: median reference 300 ms against 604 ms on the
committed benchmark's training streams). A network answering as pulses come is told neither.
So the view holds the latest windows alone, and the learner is trained as a network answers, at
any time: each epoch, each training stream is seen at T = its reference plus an offset drawn
uniformly from :data:`OFFSETS_MS` (from a rotation before the object at 600 RPM to past the
latency grid's end), and the one learner is scored on the test split's views at every delay d
of the grid. Its models and training are the static estimate's (:mod:`simlidar.bench.bound`:
an MLP and the paper's CNN, Adam, the epoch of the best validation accuracy on one draw of the
offsets, then every training stream for that many epochs, the last kept). Per d the estimate
is the best family's mean over seeds: an estimate from the learners tried, not a bound (a
stronger learner can beat it). ``benchmark/stream_estimate.py`` runs it.
"""

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from simlidar.bench.latency import US_PER_MS
from simlidar.bench.stream_task import stream_config
from simlidar.dataset.loaders import load_split, split_info
from simlidar.dataset.stream_loaders import load_stream
from simlidar.errors import ConfigError
from simlidar.generator.pulse_streams import stream_rays

# a learner family: its model (bound.BoundConfig.model) and its view (view_at): the latest
# complete window and the one firing ("-latest"), or the K latest windows begun by T ("-lastK")
FAMILIES = ("mlp-latest", "cnn-latest", "mlp-last2", "cnn-last2")
# the offsets from the reference a learner is trained at, ms: from a rotation before the object
# at 600 RPM (the shipped sensors' default) to past the latency grid's last delay
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
    arrival[sample, events.y, events.columns(config.rotation_us, config.width)] = events.t_us
    return Known(delays, emission_ns * 1e-3, arrival, labels, stream.samples["t_reference_us"],
                 len(attrs["class_names"]), config.width)  # fmt: skip


def view_at(data: Known, delay_ms, view) -> np.ndarray:
    """The (N, 2, H x K W) view of what each stream's sensor knows ``delay_ms`` (a number, or
    (N,) one a stream) after its reference time, in K windows (module docstring; a window
    that is not there is nothing: no return, not fired):

    view : an int K, the K latest windows begun by then, the current one last; or "latest",
        K = 2: the latest complete window (every pulse fired) first and the one firing, if
        any, second, so that the latest complete window has one place at every time
    """
    if view != "latest" and (isinstance(view, bool) or not isinstance(view, int) or view < 1):
        raise ConfigError(f"view={view!r}: expected a number of windows >= 1 or 'latest'")
    at = (data.reference_us + np.asarray(delay_ms) * US_PER_MS)[:, None, None]
    arrived = data.arrival_us <= at
    seen = np.stack([np.where(arrived, data.delays, 1.0), data.emission_us <= at], axis=1)
    n, _, height, _ = seen.shape
    windows = seen.reshape(n, 2, height, -1, data.width)
    nothing = np.zeros((n, 2, height, 1, data.width))
    nothing[:, 0] = 1.0
    padded = np.concatenate([nothing, windows], axis=3)  # window w at w + 1, nothing at 0
    fired = windows[:, 1]
    begun = fired.any(axis=(1, 3)).sum(axis=1)  # (N,)
    if view == "latest":
        complete = fired.all(axis=(1, 3)).sum(axis=1)
        places = np.stack([complete, np.where(begun > complete, complete + 1, 0)], axis=1)
    else:
        places = np.maximum(begun[:, None] - np.arange(view)[::-1][None, :], 0)
    index = np.broadcast_to(places[:, None, None, :, None], (n, 2, height, places.shape[1],
                                                             data.width))  # fmt: skip
    kept = np.take_along_axis(padded, index, axis=3)
    return kept.reshape(n, 2, -1).astype(np.float32)


def family_parts(family: str) -> tuple[str, int | str]:
    """A family's model and its view (:func:`view_at`): "cnn-last2" -> ("cnn", 2),
    "mlp-latest" -> ("mlp", "latest")."""
    model, _, view = family.partition("-")
    if model in ("mlp", "cnn") and view == "latest":
        return model, view
    last = view.removeprefix("last")
    if model not in ("mlp", "cnn") or not view.startswith("last") or not last.isdigit():
        raise ConfigError(
            f"family {family!r}: expected mlp-latest, cnn-latest, mlp-lastK or cnn-lastK"
        )
    if int(last) < 1:
        raise ConfigError(f"family {family!r}: expected K >= 1 windows")
    return model, int(last)


def any_time(data: Known, rng: np.random.Generator, view):
    """A function drawing the training view anew (one call an epoch): each stream at its
    reference plus an offset uniform in :data:`OFFSETS_MS` (``view``: :func:`view_at`'s)."""

    def draw() -> np.ndarray:
        return view_at(data, rng.uniform(*OFFSETS_MS, size=len(data.labels)), view)

    return draw
