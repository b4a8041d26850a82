"""Loading stream splits (docs/streams.md): their events, ragged, a whole split at a time
(:func:`load_stream`) or one sample at a time as Tonic events (:class:`StreamEventDataset`).

A stream split's dense ``delays`` read as any split's (``load_split``, ``PulseDataset``). Its
events are E rows (``event_x``, ``event_y``, ``event_t_us``, ...), sample i's the rows
``event_start[i]`` .. ``event_start[i] + event_count[i]``: both readers refuse a split whose
offsets do not tile the rows and a sample whose events lie outside its sensor or its span, in
one line naming the file (:mod:`simlidar.dataset.stream_checks`, which ``simlidar verify``
runs too).
"""

import bisect
import os
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from simlidar.dataset.loaders import (
    EVENT_DTYPE,
    MEMORY_BUDGET,
    check_tick,
    sensor_size,
    split_info,
)
from simlidar.dataset.reader import SplitInfo, load_arrays, value_problems
from simlidar.dataset.stream import NAME, SOURCE
from simlidar.dataset.stream_checks import event_limits, event_problems, first_outside
from simlidar.errors import ConfigError, DatasetError, first_line, shown
from simlidar.resources import available_memory

# the per-event datasets, by name without their prefix ("t_us": event_t_us)
EVENT_NAMES = tuple(n[6:] for n, (_, shape) in SOURCE.schema.items() if shape[0] == "E")
# the per-sample datasets load_stream returns: all but the dense delays (load_split's) and
# the events' offsets (StreamEvents')
SAMPLE_NAMES = tuple(
    n
    for n, (_, shape) in SOURCE.schema.items()
    if shape[0] == "N" and n not in ("delays", "event_start", "event_count")
)
# the per-sample and per-event datasets of a stream through a receiver (t_in_view_us;
# intensity, without its prefix), read where the split has them
RECEIVER_SAMPLE_NAMES = tuple(n for n, (_, s) in SOURCE.receiver_schema.items() if s[0] == "N")
RECEIVER_EVENT_NAMES = tuple(n[6:] for n, (_, s) in SOURCE.receiver_schema.items() if s[0] == "E")
# what ``fields`` may add to x, y, t, p (intensity: a stream through a receiver only)
EXTRA_FIELDS = ("t_us", "range_m", "surface", *RECEIVER_EVENT_NAMES)
EVENT_TYPES = {n[6:]: d for n, (d, _) in SOURCE.schema_of(True).items() if n.startswith("event_")}


def stream_info(path: str | Path, split: str) -> SplitInfo:
    """``split`` of the dataset directory ``path`` checked as every reader checks a split
    (:func:`~simlidar.dataset.loaders.split_info`), and a stream split whose delays hold a
    whole window a rotation; a DatasetError naming the file otherwise."""
    info = split_info(path, split)
    if info.source != NAME:
        raise DatasetError(
            f"{info.path}: source {info.source!r}; expected a stream split (source {NAME!r}, "
            "written by simlidar stream)"
        )
    rotations = int(info.attrs["rotations"])
    if info.width % rotations:
        raise DatasetError(
            f"{info.path}: 'delays' has {info.width} columns for {rotations} rotations; "
            "expected the same window of columns in each rotation"
        )
    return info


def _read(file: Path, names: tuple[str, ...], rows=slice(None)) -> dict[str, np.ndarray]:
    """Datasets ``names`` of one split file; an unreadable chunk is a DatasetError."""
    try:
        return load_arrays(file, names, rows)
    except OSError as exc:
        raise DatasetError(f"{file}: unreadable data ({first_line(exc)})") from None


def _offsets(info: SplitInfo, part: int) -> tuple[np.ndarray, np.ndarray]:
    """File ``part``'s ``event_start`` and ``event_count``, once they tile its events."""
    file = info.files[part]
    offsets = _read(file, ("event_start", "event_count"))
    with h5py.File(file, "r") as f:
        total = f["event_t_us"].shape[0]
    problems = event_problems(file, offsets["event_start"], offsets["event_count"], total)
    if problems:
        raise DatasetError(problems[0])
    return offsets["event_start"], offsets["event_count"]


def _checked_labels(file: Path, attrs: dict, labels: np.ndarray) -> np.ndarray:
    """``labels``, once within the split's classes."""
    problems = value_problems(file, attrs, {"labels": labels})
    if problems:
        raise DatasetError(f"{problems[0]}; expected a dataset that simlidar verify accepts")
    return labels


def _event_limits(info: SplitInfo) -> dict[str, float]:
    """:func:`event_limits` of a split's SplitInfo."""
    return event_limits(info.attrs, info.height, info.width)


@dataclass(frozen=True)
class StreamEvents:
    """A split's events, ragged: sample i's are the rows ``rows(i)`` of each per-event array.

    start, count : (N,) int64 each sample's first row and number of events
    x : (E,) uint16 column in the window; y : (E,) uint8 row (the laser, highest first)
    t_us : (E,) float64 arrival, microseconds from the stream's first firing
    p : (E,) uint8 polarity (0); range_m : (E,) float32; surface : (E,) uint8 (index into
        the split's ``surface_names``)
    intensity : (E,) uint8 the reflectivity byte, through a receiver; None without one
    """

    start: np.ndarray
    count: np.ndarray
    x: np.ndarray
    y: np.ndarray
    t_us: np.ndarray
    p: np.ndarray
    range_m: np.ndarray
    surface: np.ndarray
    intensity: np.ndarray | None = None

    def rows(self, index: int) -> slice:
        """The rows of sample ``index``'s events."""
        first = int(self.start[index])
        return slice(first, first + int(self.count[index]))

    def rotations(self, rotation_us: float) -> np.ndarray:
        """Each event's rotation, (E,) int64: the one nearest its time over ``rotation_us`` (a
        window fires within a cycle of r rotations and over its ~10 ms after)."""
        return np.round(self.t_us / rotation_us).astype(np.int64)

    def columns(self, rotation_us: float, width: int) -> np.ndarray:
        """Each event's column in its split's ``delays`` (rotations side by side), (E,) int64:
        its window's column plus ``width`` times its rotation (:meth:`rotations`)."""
        return self.rotations(rotation_us) * width + self.x


@dataclass(frozen=True)
class StreamSplit:
    """A stream split read whole (:func:`load_stream`).

    samples : every per-sample dataset but the delays, by its name in the file (N rows each):
        labels (N,) int64, t_visible_us, t_reference_us (N,) float64, object, scenario,
        layout (N,) uint8, object_track (N, R, 3), ... and through a receiver t_in_view_us
        (docs/streams.md)
    events : the events (:class:`StreamEvents`), one split's rows, its shards' joined
    attrs : the split's attributes, decoded
    files : the split's files, in sample order
    """

    samples: dict[str, np.ndarray]
    events: StreamEvents
    attrs: dict
    files: tuple[Path, ...]

    def __len__(self) -> int:
        return len(self.samples["labels"])

    @property
    def classes(self) -> list[str]:
        return list(self.attrs["class_names"])


def load_stream(path: str | Path, split: str = "train") -> StreamSplit:
    """A whole stream split, its per-sample arrays and its events, after the checks every
    reader makes (:func:`stream_info`), the events' offsets (:func:`event_problems`) and the
    values: labels within the classes, every event within the window, the one polarity, the
    surfaces and the span. The delays: ``load_split``."""
    info = stream_info(path, split)
    limits = _event_limits(info)
    received = "receiver" in info.attrs
    sample_names = SAMPLE_NAMES + (RECEIVER_SAMPLE_NAMES if received else ())
    event_names = EVENT_NAMES + (RECEIVER_EVENT_NAMES if received else ())
    samples: dict[str, list] = {n: [] for n in sample_names}
    events: dict[str, list] = {n: [] for n in ("start", "count", *event_names)}
    before = 0  # events of the files before this one
    for part, file in enumerate(info.files):
        start, count = _offsets(info, part)
        rows = _read(file, sample_names)
        _checked_labels(file, info.attrs, rows["labels"])
        mine = {n[6:]: v for n, v in _read(file, tuple(f"event_{n}" for n in event_names)).items()}
        found = first_outside(mine, limits)
        if found is not None:
            row, problem = found
            sample = int(np.searchsorted(start + count, row, side="right"))
            raise DatasetError(
                f"{file} (sample {sample}, its event {row - start[sample]}): {problem}"
            )
        for name in sample_names:
            samples[name].append(rows[name])
        for name in event_names:
            events[name].append(mine[name])
        events["start"].append(start + before)
        events["count"].append(count)
        before += int(count.sum())
    return StreamSplit(
        {n: np.concatenate(v) for n, v in samples.items()},
        StreamEvents(**{n: np.concatenate(v) for n, v in events.items()}),
        info.attrs,
        info.files,
    )


def stream_events(
    events: dict[str, np.ndarray], tick_us: float = 1.0, fields: tuple[str, ...] = ()
) -> np.ndarray:
    """One sample's events in Tonic's convention, sorted by time (ties: in the given order).

    events : the sample's per-event arrays by name (x, y, t_us, p, and ``fields``), E each
    tick_us : microseconds of one unit of ``t``
    fields : names of :data:`EXTRA_FIELDS` appended to x, y, t, p, with their own dtypes
    returns : (E,) structured array of fields x, y, t, p (int64, :data:`EVENT_DTYPE`) and
        ``fields``; t = round(t_us / tick_us), the arrival in ticks from the first firing
    """
    order = np.argsort(events["t_us"], kind="stable")
    extra = [(n, events[n].dtype) for n in fields]
    out = np.zeros(len(order), np.dtype(EVENT_DTYPE.descr + extra))
    for name in ("x", "y", "p", *fields):
        out[name] = events[name][order]
    out["t"] = np.round(events["t_us"][order] / tick_us).astype(np.int64)
    return out


def _checked_fields(fields) -> tuple[str, ...]:
    """``fields`` as a tuple of distinct :data:`EXTRA_FIELDS` (None: none)."""
    if fields is None:
        return ()
    names = tuple(fields) if isinstance(fields, list | tuple) else ()
    known = all(isinstance(n, str) and n in EXTRA_FIELDS for n in names)
    if not isinstance(fields, list | tuple) or not known or len(set(names)) != len(names):
        raise ConfigError(
            f"fields={shown(fields)}: expected a tuple of distinct names from {list(EXTRA_FIELDS)}"
        )
    return names


def _checked_tick(tick_us, span_us: float) -> float:
    """``tick_us``, once a positive number of microseconds, at most the span and not so short
    that the span holds more than :data:`MAX_WINDOW_TICKS` ticks (:func:`check_tick`)."""
    hint = f"the stream spans {span_us:.10g} us; tick_us=1 gives microseconds, 0.001 nanoseconds"
    check_tick(tick_us, span_us, "us", f"the {span_us:.10g} us stream", hint)
    return float(tick_us)


class StreamEventDataset:
    """A stream split as events, in the manner of ``tonic.datasets``: sample ``i`` is
    (:func:`stream_events` of its events, label). Needs no torch; a ``DataLoader`` takes it
    (with ``num_workers > 0`` once a transform makes the events a fixed shape).

    path : the dataset directory; split : "train" or "test"
    transform : optional callable applied to the events (a Tonic transform, e.g. ``ToFrame``)
    target_transform : optional callable applied to the label (an int)
    tick_us : microseconds of one unit of an event's ``t`` (default 1, Tonic's unit), at most
        the stream's span and at least 2**-53 of it
    fields : names of :data:`EXTRA_FIELDS` appended to each event after x, y, t, p, e.g.
        ``("surface", "range_m")``

    The split's offsets are checked when made (:func:`event_problems`), each sample's values
    as it is read (a DatasetError naming the file and the sample). Attributes as Tonic's
    datasets have them: ``sensor_size`` (W window columns, H rows, 1), ``dtype``,
    ``ordering`` (its field names), ``classes`` (the class names); and ``labels`` (N,),
    ``t_reference_us`` (N,) (the time latencies count from), ``span_us``, ``tick_us``,
    ``fields``.

    On the first sample the split's events (the fields a sample reads) are read into memory,
    whole, where they fit ``memory_budget`` (``MEMORY_BUDGET`` when made, 512 MiB: about 45
    million events of x, y, t, p) and the memory the process has; a larger split's samples are
    read from the files, opened once in each process that reads (a forked ``DataLoader``
    worker keeps what its parent read and opens its own files; neither is pickled). This is
    ``PulseDataset``'s rule, not its code: its blocks are chunks of whole rows of the samples,
    where a sample's events are a run of rows of its own length.
    """

    def __init__(
        self,
        path: str | Path,
        split: str = "train",
        transform=None,
        target_transform=None,
        tick_us: float = 1.0,
        fields: tuple[str, ...] | None = None,
    ):
        info = stream_info(path, split)
        self.span_us = float(info.attrs["span_us"])
        self.tick_us = _checked_tick(tick_us, self.span_us)
        self.fields = _checked_fields(fields)
        missing = [
            n for n in self.fields if n in RECEIVER_EVENT_NAMES and "receiver" not in info.attrs
        ]
        if missing:
            raise ConfigError(
                f"fields={shown(fields)}: {info.path} has no {missing[0]} (a stream without a "
                "receiver); expected a stream made with --profile sensor"
            )
        self.transform = transform
        self.target_transform = target_transform
        self.files = info.files
        self.classes = list(info.attrs["class_names"])
        self.sensor_size = sensor_size(info.width // int(info.attrs["rotations"]), info.height)
        self._limits = _event_limits(info)
        extra = [(n, EVENT_TYPES[n]) for n in self.fields]
        self.dtype = np.dtype(EVENT_DTYPE.descr + extra)
        self.ordering = self.dtype.names
        self._first = tuple(int(n) for n in np.cumsum((0, *info.sizes)))  # each file's first
        offsets, labels, reference = [], [], []
        for part, file in enumerate(info.files):
            offsets.append(_offsets(info, part))
            rows = _read(file, ("labels", "t_reference_us"))
            labels.append(_checked_labels(file, info.attrs, rows["labels"]))
            reference.append(rows["t_reference_us"])
        self._offsets = offsets
        self.labels = np.concatenate(labels)
        self.t_reference_us = np.concatenate(reference)
        self.memory_budget = MEMORY_BUDGET
        self._whole = None  # whether the events are read whole; decided on the first sample
        self._arrays = {}  # the events read whole, by position in self.files
        self._h5 = None  # (open file, its datasets), by position in self.files
        self._pid = None  # the process that opened them

    def __len__(self) -> int:
        return len(self.labels)

    def __getitem__(self, index: int):
        size = len(self.labels)
        if not -size <= index < size:
            raise IndexError(f"index {index} out of range for {size} samples")
        index %= size
        part = bisect.bisect_right(self._first, index) - 1
        row = index - self._first[part]
        start, count = self._offsets[part]
        rows = slice(int(start[row]), int(start[row] + count[row]))
        events = self._events(part, rows)
        found = first_outside(events, self._limits)
        if found is not None:
            raise DatasetError(
                f"{self.files[part]} (sample {row}, its event {found[0]}): {found[1]}"
            )
        events = stream_events(events, self.tick_us, self.fields)
        label = int(self.labels[index])
        if self.transform is not None:
            events = self.transform(events)
        if self.target_transform is not None:
            label = self.target_transform(label)
        return events, label

    def _events(self, part: int, rows: slice) -> dict[str, np.ndarray]:
        """Rows ``rows`` of file ``part``'s per-event datasets that a sample reads, by name
        without their prefix: from the split's events read whole on the first sample where
        they fit ``memory_budget`` and this process's memory, else from the datasets."""
        names = ("x", "y", "t_us", "p", *self.fields)
        if self._whole is None:
            row = sum(np.dtype(EVENT_TYPES[n]).itemsize for n in names)
            need = row * sum(int(count.sum()) for _, count in self._offsets)
            room = available_memory()
            self._whole = need <= self.memory_budget and (room is None or need <= room)
        file = self.files[part]
        if self._whole:
            if part not in self._arrays:
                read = _read(file, tuple(f"event_{n}" for n in names))
                self._arrays[part] = {n[6:]: values for n, values in read.items()}
            return {n: values[rows] for n, values in self._arrays[part].items()}
        try:
            return {n: ds[rows] for n, ds in self._datasets(part).items()}
        except OSError as exc:
            raise DatasetError(f"{file}: unreadable data ({first_line(exc)})") from None

    def _datasets(self, part: int) -> dict[str, h5py.Dataset]:
        """File ``part``'s per-event datasets that a sample reads, by name without their
        prefix, opened once in each process that reads from it. They stay open: HDF5 keeps a
        dataset's last chunks while it is, and a chunk (65,536 events) holds a score of
        samples."""
        if self._pid != os.getpid():  # a forked worker drops the copies of its parent's
            self._h5, self._pid = {}, os.getpid()
        if part not in self._h5:
            f = h5py.File(self.files[part], "r")
            names = ("x", "y", "t_us", "p", *self.fields)
            self._h5[part] = (f, {n: f[f"event_{n}"] for n in names})
        return self._h5[part][1]

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state["_h5"], state["_pid"], state["_arrays"] = None, None, {}
        return state

    def __del__(self) -> None:
        if getattr(self, "_pid", None) != os.getpid():
            return  # handles a forked worker inherited are its parent's
        for f, _ in (getattr(self, "_h5", None) or {}).values():
            try:
                f.close()
            except Exception:  # h5py half torn down at interpreter exit
                pass
