"""Latency metrics of the stream task (issue 60): how a network's accuracy grows with time.

Clocks: every time is on the sensor's clock in microseconds (``_us``) from the stream's first
firing; delays and latencies are in milliseconds (``_ms``) after a sample's reference time
``t_reference_us`` (its first event on the object; for a sample without an object, one of its
returns drawn from the same range). An answer at time t is in force from t itself (an answer
at exactly the time asked counts) until the sample's next answer; before its first answer a
sample has no prediction, which counts as wrong.

Span rule: a figure at delay d counts only the samples whose ``t_reference_us + d`` is at or
before the stream's end ``span_us``, and says how many it counted. A sample whose delay runs past
the end is left out, never scored with an answer of another time, so no figure mixes clocks.
"""

import math
from dataclasses import dataclass

import numpy as np

from simlidar.errors import ConfigError, shown

DELAYS_MS = (0.5, 1, 2, 5, 10, 20, 50, 100)  # the delays accuracy_after reports by default
US_PER_MS = 1000.0


def _numbers(name: str, value, kinds: str = "fiu") -> np.ndarray:
    """``value`` as a float64 array (int64 for ``kinds="iu"``), refused if of another kind."""
    a = np.asarray(value)
    if a.dtype.kind not in kinds:
        wanted = "integers" if kinds == "iu" else "numbers"
        raise ConfigError(f"{name}: expected {wanted}, got {shown(value)} ({a.dtype})")
    return a.astype(np.int64 if kinds == "iu" else np.float64)


def _shaped(name: str, a: np.ndarray, shape: tuple, finite: bool = True) -> np.ndarray:
    if a.shape != shape:
        raise ConfigError(f"{name}: expected shape {shape}, got {a.shape}")
    if finite and not np.isfinite(a).all():
        raise ConfigError(f"{name}: expected finite values, got {shown(a[~np.isfinite(a)][0])}")
    return a


def _number(name: str, value) -> float:
    """A finite number >= 0 as a float (a bool is no number)."""
    if isinstance(value, bool) or not isinstance(value, int | float | np.number):
        raise ConfigError(f"{name}: {shown(value)}: expected a number")
    if not (math.isfinite(value) and value >= 0):
        raise ConfigError(f"{name}: {shown(value)}: expected a finite number >= 0")
    return float(value)


def _count(name: str, value) -> int:
    """An integer >= 1 (a bool is none)."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise ConfigError(f"{name}: {shown(value)}: expected an integer >= 1")
    return int(value)


def _json(x: float) -> float | None:
    return None if math.isnan(x) else float(x)


def _plain(result, skip: tuple = ()) -> dict:
    """A result's fields for JSON: tuples as lists, NaN as None."""

    def one(v):
        if isinstance(v, tuple):
            return [one(x) for x in v]
        return _json(v) if isinstance(v, float) else v

    return {name: one(v) for name, v in result.__dict__.items() if name not in skip}


_BAD_SLOT = (  # what Answers says of a sample's first bad slot k (k1 = k + 1)
    "class {c} in slot {k}: expected -1 or [0, {top})",
    "slot {k} has time {t} and class {c}: expected a finite time and a class >= 0, or NaN and -1",
    "an answer in slot {k1} after an unused slot: expected the unused slots last",
    "times_us not in time order: {t1} in slot {k1} after {t}: expected non-decreasing times",
)


@dataclass(frozen=True, eq=False)
class Answers:
    """Each sample's answers in time order, padded to K slots (the unused ones last).

    times_us : (N, K) float64, sensor clock, non-decreasing per sample; NaN in unused slots
    classes : (N, K) int64, the class answered; -1 in unused slots
    n_classes : the number of classes when known: a class outside [0, n_classes) is refused
    Two answers of a sample at the same time: the later slot is the one in force.
    """

    times_us: np.ndarray
    classes: np.ndarray
    n_classes: int | None = None

    def __post_init__(self):
        times = _numbers("times_us", self.times_us)
        classes = _numbers("classes", self.classes, "iu")
        if times.ndim != 2 or classes.shape != times.shape:
            raise ConfigError(
                f"Answers: times_us of shape {times.shape}, classes of shape {classes.shape}:"
                " expected two arrays of one shape (N, K)"
            )
        top = np.inf if self.n_classes is None else _count("n_classes", self.n_classes)
        used = classes >= 0
        bad_slots = (  # one mask per message of _BAD_SLOT
            (classes < -1) | (classes >= top),
            used != np.isfinite(times),
            used[:, 1:] & ~used[:, :-1],
            np.diff(times, axis=1) < 0,  # NaN compares False
        )
        for bad, say in zip(bad_slots, _BAD_SLOT):  # the first bad (sample, slot) of each
            if bad.any():
                i, k = np.argwhere(bad)[0]
                t, c, k1 = times[i, k], classes[i, k], min(k + 1, times.shape[1] - 1)
                top = self.n_classes or "n_classes"
                say = say.format(t=t, c=c, k=k, k1=k1, t1=times[i, k1], top=top)
                raise ConfigError(f"Answers: sample {i}: {say}")
        times[~used] = np.nan  # an unused +inf would otherwise be "in force" at t = inf
        for name, a in (("times_us", times), ("classes", classes)):
            a.setflags(write=False)
            object.__setattr__(self, name, a)

    def __len__(self) -> int:
        return len(self.times_us)

    def at(self, t_us) -> np.ndarray:
        """The class in force at each sample's time, (N,) int64; -1: no answer yet.

        t_us : (N,) float, or one time for all, sensor clock (an answer at exactly t_us is in
            force)
        """
        t = _numbers("t_us", t_us)
        t = _shaped("t_us", np.full(len(self), t) if t.ndim == 0 else t, (len(self),), False)
        if np.isnan(t).any():
            raise ConfigError("t_us: expected times, got NaN")
        count = (self.times_us <= t[:, None]).sum(axis=1)  # answers made by t; NaN slots never
        padded = np.concatenate([np.full((len(t), 1), -1), self.classes], axis=1)
        return padded[np.arange(len(t)), count]  # slot 0: "no answer yet"

    @classmethod
    def from_frames(cls, frame_end_us, classes, n_classes: int | None = None) -> "Answers":
        """A frame-based network's answers: each at its frame's end, so that its latency is its
        frame clock by construction.

        frame_end_us : (F,) or (N, F) float, sensor clock, increasing (see :func:`frame_ends_us`)
        classes : (N, F) int, the class answered at each frame's end; -1: no answer at that
            frame (the answer before it stays in force)
        """
        classes = _numbers("classes", classes, "iu")
        if classes.ndim != 2:
            raise ConfigError(f"classes: expected shape (N, F), got {classes.shape}")
        ends = _numbers("frame_end_us", frame_end_us)
        if ends.shape == classes.shape[1:]:  # (F,): every sample's frames end together
            ends = np.broadcast_to(ends, classes.shape)
        _shaped("frame_end_us", ends, classes.shape)
        if (np.diff(ends, axis=1) <= 0).any():
            i, k = np.argwhere(np.diff(ends, axis=1) <= 0)[0]
            say = f"{ends[i, k + 1]} after {ends[i, k]} (frame {k + 1}): expected increasing ends"
            raise ConfigError(f"frame_end_us: {say}")
        times = np.where(classes >= 0, ends, np.nan)
        order = np.argsort(classes < 0, axis=1, kind="stable")  # answers first, in frame order
        take = np.take_along_axis
        return cls(take(times, order, axis=1), take(classes, order, axis=1), n_classes)

    @classmethod
    def from_decisions(cls, decision_us, classes, n_classes: int | None = None) -> "Answers":
        """A network that answers once (an event-driven TTFS network's first output spike).

        decision_us : (N,) float, sensor clock; NaN or +inf: never answered
        classes : (N,) int, the class decided; -1: never answered
        """
        classes = _numbers("classes", classes, "iu")
        if classes.ndim != 1:
            raise ConfigError(f"classes: expected shape (N,), got {classes.shape}")
        t = _shaped("decision_us", _numbers("decision_us", decision_us), classes.shape, False)
        if np.isneginf(t).any():
            raise ConfigError("decision_us: expected times, NaN or +inf (never), got -inf")
        never = ~np.isfinite(t) | (classes == -1)
        times, classes = np.where(never, np.nan, t), np.where(never, -1, classes)
        return cls(times[:, None], classes[:, None], n_classes)


def _truth(answers: Answers, labels, t_reference_us) -> tuple[np.ndarray, np.ndarray]:
    """labels (N,) int64 and t_reference_us (N,) float64, checked against ``answers``."""
    n = len(answers)
    labels = _shaped("labels", _numbers("labels", labels, "iu"), (n,))
    top = answers.n_classes if answers.n_classes is not None else np.inf
    if ((labels < 0) | (labels >= top)).any():
        bad = labels[(labels < 0) | (labels >= top)][0]
        raise ConfigError(
            f"labels: {bad}: expected classes in [0, {answers.n_classes or 'n_classes'})"
        )
    return labels, _shaped("t_reference_us", _numbers("t_reference_us", t_reference_us), (n,))


def _span_end(span_us, n: int) -> np.ndarray | None:
    """span_us (a number or (N,)) as (N,) float64; None stays None."""
    if span_us is None:
        return None
    end = _numbers("span_us", span_us)
    return _shaped("span_us", np.broadcast_to(end, (n,)) if end.ndim == 0 else end, (n,))


@dataclass(frozen=True)
class AccuracyAfter:
    """Accuracy at fixed delays after the reference (:func:`accuracy_after`).

    delays_ms : the delays (ms)
    accuracy : per delay, over the ``counts`` samples whose reference + delay is within the span
        (NaN where none is)
    counts : per delay, the samples counted
    end_accuracy : of the prediction in force at ``span_us``, over all samples (NaN without it)
    samples : all samples
    """

    delays_ms: tuple[float, ...]
    accuracy: tuple[float, ...]
    counts: tuple[int, ...]
    end_accuracy: float
    samples: int

    def to_dict(self) -> dict:
        """For JSON: NaN becomes None."""
        return _plain(self)


def accuracy_after(
    answers: Answers, labels, t_reference_us, delays_ms=DELAYS_MS, span_us=None
) -> AccuracyAfter:
    """For each delay d, the accuracy of the prediction in force at ``t_reference_us + d``
    (no answer yet: wrong), over the samples for which that time is at or before ``span_us``
    (the module's span rule); and the accuracy at ``span_us`` itself.

    answers : the network's answers for N samples
    labels : (N,) int, each sample's class
    t_reference_us : (N,) float, sensor clock (us)
    delays_ms : the delays (ms, >= 0)
    span_us : the stream's end (us; a number or (N,)); None: every sample counts at every delay
    """
    labels, ref = _truth(answers, labels, t_reference_us)
    delays = _numbers("delays_ms", delays_ms)
    if delays.ndim != 1 or not np.isfinite(delays).all() or (delays < 0).any():
        raise ConfigError(f"delays_ms: {shown(delays_ms)}: expected finite delays >= 0 (ms)")
    end = _span_end(span_us, len(labels))
    accuracy, counts = [], []
    for d in delays:
        t = ref + d * US_PER_MS
        keep = np.ones(len(t), bool) if end is None else t <= end
        right = answers.at(t) == labels
        counts.append(int(keep.sum()))
        accuracy.append(float(right[keep].mean()) if keep.any() else math.nan)
    at_end = math.nan
    if end is not None and len(labels):
        at_end = float((answers.at(end) == labels).mean())
    return AccuracyAfter(
        tuple(map(float, delays)), tuple(accuracy), tuple(counts), at_end, len(labels)
    )


@dataclass(frozen=True, eq=False)
class DecisionLatency:
    """When each sample first answers (:func:`decision_latency`).

    latency_ms : (N,) float64, first answer time minus the reference (ms); NaN: never answered;
        negative: answered before the reference (a guess from the background)
    first_accuracy : accuracy of the first answers over all samples (never answered: wrong)
    samples, answered, before_reference : samples; those that answered; those that answered
        before their reference
    median_ms, q05_ms, q95_ms : the latency's median and 5 % and 95 % quantiles over the samples
        that answered (numpy's linear interpolation; NaN if none did)
    """

    latency_ms: np.ndarray
    first_accuracy: float
    samples: int
    answered: int
    before_reference: int
    median_ms: float
    q05_ms: float
    q95_ms: float

    def to_dict(self) -> dict:
        """The summary for JSON (not the per-sample latencies), with shares over all samples."""
        n, before = self.samples or math.nan, self.before_reference  # 0 samples: shares None
        return _plain(self, skip=("latency_ms",)) | {
            "share_at_or_after": _json((self.answered - before) / n),
            "share_before": _json(before / n),
            "share_never": _json((self.samples - self.answered) / n),
        }


def decision_latency(answers: Answers, labels, t_reference_us) -> DecisionLatency:
    """Each sample's first answer: its latency after the reference (ms) and its accuracy.

    Meant for a network that answers once (:meth:`Answers.from_decisions`); a frame-based
    network's first answer is its first frame's end, often before the reference (read it with
    :func:`accuracy_after` and :func:`area_under_curve`).
    labels : (N,) int; t_reference_us : (N,) float, sensor clock (us)
    """
    labels, ref = _truth(answers, labels, t_reference_us)
    pad = ((0, 0), (0, 1))  # a "never answered" slot after the last, for K = 0
    first_us = np.pad(answers.times_us, pad, constant_values=np.nan)[:, 0]
    first_class = np.pad(answers.classes, pad, constant_values=-1)[:, 0]
    latency_ms = (first_us - ref) / US_PER_MS
    latency_ms.setflags(write=False)
    done = latency_ms[~np.isnan(latency_ms)]
    q05, median, q95 = np.quantile(done, [0.05, 0.5, 0.95]) if len(done) else [math.nan] * 3
    right = float((first_class == labels).mean()) if len(labels) else math.nan
    counts = (len(labels), len(done), int((done < 0).sum()))
    return DecisionLatency(latency_ms, right, *counts, float(median), float(q05), float(q95))


@dataclass(frozen=True)
class CurveArea:
    """The normalised area under accuracy-vs-delay (:func:`area_under_curve`).

    horizon_ms : the curve's extent (ms); area : in [0, 1] (NaN if no sample counted);
    counted : samples whose reference + horizon is within the span; samples : all samples
    """

    horizon_ms: float
    area: float
    counted: int
    samples: int

    def to_dict(self) -> dict:
        """For JSON: NaN becomes None."""
        return _plain(self)


def area_under_curve(
    answers: Answers, labels, t_reference_us, horizon_ms: float = 100.0, span_us=None
) -> CurveArea:
    """(1 / H) * integral over delays d in [0, H] of the accuracy in force at reference + d,
    H = ``horizon_ms``: 1.0 is right from the reference (the first event on the object) on, 0.5
    right for the second half of the horizon. Exact: the prediction in force changes only at
    answer times, so each sample's share is the length of its correct answers' intervals inside
    [reference, reference + H], summed, over H; no grid.

    answers : the network's answers for N samples
    labels : (N,) int, each sample's class
    t_reference_us : (N,) float, sensor clock (us)
    horizon_ms : H (ms, > 0)
    span_us : the stream's end (us; a number or (N,)): a sample counts only if reference + H is at
        or before it (the span rule of :func:`accuracy_after`); None: every sample counts
    """
    labels, ref = _truth(answers, labels, t_reference_us)
    if _number("horizon_ms", horizon_ms) == 0:
        raise ConfigError("horizon_ms: 0: expected a delay > 0 (ms)")
    horizon_us = float(horizon_ms) * US_PER_MS
    start = answers.times_us  # (N, K); NaN in unused slots, which are never right below
    stop = np.concatenate([start[:, 1:], np.full((len(start), 1), np.nan)], axis=1)
    stop = np.where(np.isnan(stop), np.inf, stop)  # the last answer holds for ever
    lo, hi = ref[:, None], ref[:, None] + horizon_us
    inside = np.clip(np.minimum(stop, hi) - np.maximum(start, lo), 0.0, None)  # (N, K) us
    share = np.where(answers.classes == labels[:, None], inside, 0.0).sum(axis=1) / horizon_us
    end = _span_end(span_us, len(labels))
    keep = np.ones(len(ref), bool) if end is None else ref + horizon_us <= end
    area = float(share[keep].mean()) if keep.any() else math.nan
    return CurveArea(float(horizon_ms), area, int(keep.sum()), len(labels))


def frame_ends_us(
    rotations: int, rotation_us: float, window_last_firing_us: float, max_tof_us: float = 0.0
) -> np.ndarray:
    """When a frame-based network can answer: the end of each rotation's window, its last firing
    plus the longest time of flight, (rotations,) float64 on the sensor clock (us):
    ``r * rotation_us + window_last_firing_us + max_tof_us`` for r = 0 .. rotations - 1.

    window_last_firing_us : the window's last firing after its rotation's start, in
        [0, rotation_us)
    """
    rotations = _count("rotations", rotations)
    rotation, tof = _number("rotation_us", rotation_us), _number("max_tof_us", max_tof_us)
    last = _number("window_last_firing_us", window_last_firing_us)
    if rotation == 0 or last >= rotation:
        raise ConfigError(
            f"window_last_firing_us {last} in rotation_us {rotation}: expected a rotation > 0 us"
            " whose window's last firing comes before its end"
        )
    return np.arange(rotations) * rotation + last + tof


def mean_interval(values, confidence: float = 0.95) -> tuple[float, float]:
    """The mean of ``values`` (one figure per seed) and the half-width of its Student's t
    confidence interval: t_{(1 + confidence) / 2, n - 1} * s / sqrt(n), s with n - 1."""
    from scipy.stats import t

    v = _numbers("values", values)
    if v.ndim != 1 or len(v) < 2:
        raise ConfigError(f"values: {shown(values)}: expected 2 values or more (one per seed)")
    _shaped("values", v, v.shape)
    if not 0 < _number("confidence", confidence) < 1:
        raise ConfigError(f"confidence: {shown(confidence)}: expected a level in (0, 1)")
    half = t.ppf(0.5 + confidence / 2, len(v) - 1) * v.std(ddof=1) / math.sqrt(len(v))
    return float(v.mean()), float(half)
