"""Loading simlidar datasets: numpy arrays, a torch ``Dataset``, and spike events.

Examples (tested) are in ``docs/loading.md``.
"""

import bisect
import math
import os
from collections import OrderedDict
from pathlib import Path

import h5py
import numpy as np

from simlidar.dataset.reader import SplitInfo, load_arrays, read_split, value_problems
from simlidar.dataset.schema import CHUNK_SAMPLES, WAVEFORM_SCHEMA, generated_schema
from simlidar.errors import ConfigError, DatasetError, shown
from simlidar.resources import available_memory, check_memory
from simlidar.settings import Range

# Tonic's event layout (its N-MNIST's): x column, y row, t time in ticks, p polarity
EVENT_DTYPE = np.dtype([("x", np.int64), ("y", np.int64), ("t", np.int64), ("p", np.int64)])
TICK_NS = 1000.0  # the default tick of an event's time: one microsecond, Tonic's time unit


def split_info(path: str | Path, split: str) -> SplitInfo:
    """``split`` of the dataset directory ``path``, checked (schema, version, shards): its
    files, sizes and attributes."""
    if split not in ("train", "test"):
        raise DatasetError(f"split {split!r}: expected 'train' or 'test'")
    return read_split(path, split)


def split_files(path: str | Path, split: str) -> list[Path]:
    """The files of ``split`` in the dataset directory ``path``, in sample order: ``train.h5``,
    or its shards (``train-00000-of-00004.h5``, ...; docs/dataset-format.md)."""
    return list(split_info(path, split).files)


def split_path(path: str | Path, split: str) -> Path:
    """The file of ``split`` in the dataset directory ``path`` (checked to be a split); a split
    written as shards has several: :func:`split_files`."""
    info = split_info(path, split)
    if info.sharded:
        raise DatasetError(
            f"{path}: the {split} split is {len(info.files)} shard files; expected one file "
            "(use split_files, or load_split and PulseDataset, which read shards)"
        )
    return info.path


def load_split(path: str | Path, split: str = "train", field: str = "delays"):
    """A whole split as numpy arrays (one file or its shards).

    returns : x (N, H, W) float32 (``field``: "delays" with noise, or "clean_delays" of a
        generated dataset; H = 16 there; another per-pixel field of a generated split, or
        "waveform", (N, H, W, T) float32 watts, of one generated with ``--waveform-bin``),
        y (N,) int64 class labels
    """
    info = _field_checked(split_info(path, split), field, PIXEL_FIELDS)
    arrays = info.read((field, "labels"))
    where = info.path.parent / f"{split}-*.h5" if info.sharded else info.path
    _check_values(where, info.attrs, arrays)
    return arrays[field], arrays["labels"]


def _check_values(where, attrs: dict, arrays: dict[str, np.ndarray]) -> None:
    """Refuse values read from a split that no reader may return (delays outside [0, 1],
    labels outside the classes: :func:`~simlidar.dataset.reader.value_problems`), in one line
    starting with ``where`` (the file, and the sample where one was read)."""
    problems = value_problems(where, attrs, arrays)
    if problems:
        raise DatasetError(f"{problems[0]}; expected a dataset that simlidar verify accepts")


FIELDS = ("delays", "clean_delays")  # what the datasets of samples read as a sample
# what load_split reads: a generated split's per-pixel datasets, (N, H, W) each
PIXEL_FIELDS = tuple(
    name
    for name, (_, tail) in generated_schema("scan", receiver=True).items()
    if len(tail(1, 1)) == 2
) + tuple(WAVEFORM_SCHEMA)


def _field_checked(info: SplitInfo, field, allowed: tuple[str, ...] = FIELDS) -> SplitInfo:
    """``info``, once ``field`` is one of ``allowed`` held by its files (a converted split has
    no ``clean_delays``); a ConfigError or DatasetError naming it otherwise."""
    if not isinstance(field, str) or field not in allowed:
        raise ConfigError(f"field={shown(field)}: expected one of {list(allowed)}")
    with h5py.File(info.files[0], "r") as f:
        if field not in f:
            raise DatasetError(
                f"{info.files[0]}: no dataset {field!r}; expected a split that holds it "
                "('clean_delays': a generated one)"
            )
    return info


# A split whose requested rows (the delays and the labels) take at most this many bytes is read
# into memory whole on its first sample, by each process that reads it: the paper's 3,000
# samples are 3.1 MB, a 512 MiB split is 500,000 VLP-16 samples of 16 x 16 or 22,000 KITTI
# crops. A larger one keeps the CACHE_CHUNKS chunks of CHUNK_SAMPLES rows it read last.
MEMORY_BUDGET = 512 * 2**20
CACHE_CHUNKS = 4  # decompressed chunks a split larger than its budget keeps (LRU)


class _SplitRows:
    """One split's samples read by index: (delays (H, W) float32 numpy, label), and its
    ``classes`` (the class names, in label order).

    The requested rows are read from HDF5 a block at a time: the whole split on the first
    sample where it fits ``memory_budget`` (:data:`MEMORY_BUDGET` when made) and the memory
    this process has, else the chunk of :data:`CHUNK_SAMPLES` rows holding the sample, the
    last :data:`CACHE_CHUNKS` kept. Each block's values are checked once as it is read
    (:func:`_check_values`); a block that fails is checked again sample by sample, so that the
    sound samples of a damaged file still read and a bad one is refused naming it. A sample
    is returned as a copy: a transform may change it in place.

    Nothing is read or opened until the first sample, and neither blocks nor HDF5 handles are
    pickled to ``DataLoader`` workers; a worker forked after its parent read keeps the
    parent's blocks and opens its own files (h5py handles do not survive a fork).
    """

    def __init__(self, path: str | Path, split: str, field: str):
        info = _field_checked(split_info(path, split), field)
        self.info = info
        self.files = info.files
        self.starts = tuple(int(n) for n in np.cumsum((0, *info.sizes)))  # each file's first
        self.field = field
        self.size = info.size
        self.classes = list(info.attrs["class_names"])
        self.memory_budget = MEMORY_BUDGET
        self._whole = None  # whether the split is read whole; decided on the first sample
        self._blocks = OrderedDict()  # (file, first row) -> (arrays, sound), oldest first
        self._h5 = None  # open files, by position in self.files
        self._pid = None  # the process that opened them

    def __len__(self) -> int:
        return self.size

    def _row(self, index: int) -> tuple[np.ndarray, int]:
        if not -self.size <= index < self.size:
            raise IndexError(f"index {index} out of range for {self.size} samples")
        index %= self.size
        part = bisect.bisect_right(self.starts, index) - 1
        row = index - self.starts[part]
        first, arrays, sound = self._block(part, row)
        delays, label = arrays[self.field][row - first].copy(), arrays["labels"][row - first]
        if not sound:
            where = f"{self.files[part]} (sample {row})"
            _check_values(where, self.info.attrs, {self.field: delays, "labels": label})
        return delays, int(label)

    def _block(self, part: int, row: int) -> tuple[int, dict[str, np.ndarray], bool]:
        """The block of file ``part`` holding its ``row``: its first row, its arrays (the
        field and the labels) and whether all its values are sound."""
        if self._whole is None:
            self._whole = self._fits()
        first = 0 if self._whole else row - row % CHUNK_SAMPLES
        key = (part, first)
        if key in self._blocks:
            self._blocks.move_to_end(key)
            return (first, *self._blocks[key])
        names = (self.field, "labels")
        if self._whole:
            arrays = load_arrays(self.files[part], names)
        else:
            f = self._file(part)
            arrays = {n: f[n][first : first + CHUNK_SAMPLES] for n in names}
            while len(self._blocks) >= CACHE_CHUNKS:
                self._blocks.popitem(last=False)
        sound = not value_problems(self.files[part], self.info.attrs, arrays)
        self._blocks[key] = (arrays, sound)
        return first, arrays, sound

    def _fits(self) -> bool:
        """Whether the split's requested rows fit ``memory_budget`` and this process's memory;
        where not, a ResourceError if even :data:`CACHE_CHUNKS` chunks do not."""
        names = (self.field, "labels")
        with h5py.File(self.files[0], "r") as f:
            row = sum(f[n].dtype.itemsize * math.prod(f[n].shape[1:]) for n in names)
        room = available_memory()
        if self.size * row <= self.memory_budget and (room is None or self.size * row <= room):
            return True
        check_memory(
            CACHE_CHUNKS * CHUNK_SAMPLES * row,
            f"{self.files[0]}: {CACHE_CHUNKS} chunks of {CHUNK_SAMPLES} rows of {list(names)}",
        )
        return False

    def _file(self, part: int) -> h5py.File:
        """File ``part``, opened once in each process that reads from it."""
        if self._pid != os.getpid():  # a forked worker drops the copies of its parent's
            self._h5, self._pid = {}, os.getpid()
        if part not in self._h5:
            self._h5[part] = h5py.File(self.files[part], "r")
        return self._h5[part]

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state["_h5"], state["_pid"], state["_blocks"] = None, None, OrderedDict()
        return state

    def __del__(self) -> None:
        if getattr(self, "_pid", None) != os.getpid():
            return  # handles a forked worker inherited are its parent's
        for f in (getattr(self, "_h5", None) or {}).values():
            try:
                f.close()
            except Exception:  # h5py half torn down at interpreter exit
                pass


class _PulseSplit(_SplitRows):
    """A ``torch.utils.data.Dataset`` over one split: (delays as a float tensor, label), the
    values :func:`load_split` returns, read into memory or a chunk at a time in each process
    (``DataLoader`` workers too): :class:`_SplitRows`; ``classes``: the class names.

    transform : optional callable applied to the (H, W) float tensor
    target_transform : optional callable applied to the label (an int)
    field : "delays" (with noise, the default) or "clean_delays"
    """

    def __init__(
        self,
        path: str | Path,
        split: str = "train",
        transform=None,
        field: str = "delays",
        target_transform=None,
    ):
        super().__init__(path, split, field)
        self.transform = transform
        self.target_transform = target_transform

    def __getitem__(self, index: int):
        import torch

        delays, label = self._row(index)
        x = torch.from_numpy(delays)
        if self.transform is not None:
            x = self.transform(x)
        if self.target_transform is not None:
            label = self.target_transform(label)
        return x, label


def __getattr__(name: str):
    """``PulseDataset`` is made on first use, so that importing this module needs no torch."""
    if name == "PulseDataset":
        import torch.utils.data

        cls = type(
            "PulseDataset",
            (_PulseSplit, torch.utils.data.Dataset),
            {"__module__": __name__, "__doc__": _PulseSplit.__doc__},
        )
        globals()[name] = cls
        return cls
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def spike_threshold(attrs: dict) -> float:
    """Delays at or above this value are no input spike, by a split's attributes: ``inf`` when
    every pixel is a spike (``input_spikes = "all"``, the paper profile), else the
    ``no_return_delay`` (1.0: the physical profile, converted data and files without it)."""
    if attrs.get("input_spikes", "returns") == "all":
        return float("inf")
    return float(attrs.get("no_return_delay", 1.0))


def delay_unit_ns(attrs: dict) -> float | None:
    """Nanoseconds of a delay of 1.0, by a split's attributes: ``delay_unit_ns`` for scan-timed
    pulses (the sweep window, about 10.1 ms for a 36-degree VLP-16 window), ``tof_max_ns`` for
    flash pulses and converted KITTI crops (667.13 ns at 100 m); None for data that are not
    LiDAR times (a DVS split's unit is its ``time_window_us``)."""
    for key in ("delay_unit_ns", "tof_max_ns"):
        if key in attrs:
            return float(attrs[key])
    return None


def sensor_size(width: int, height: int) -> tuple[int, int, int]:
    """Tonic's ``sensor_size`` of a sample: (W columns, H rows, 1 polarity)."""
    return (width, height, 1)


# the most ticks a window may span: an event's t is an int64, and a tick of 1e-300 ns made
# every t INT64_MIN; 2**53 keeps every t exact as a float too
MAX_WINDOW_TICKS = 2**53


def check_tick(tick, span: float, unit: str, what: str, hint: str) -> None:
    """Refuse a tick (``tick``, in ``unit``: "ns" or "us") that is not a positive number, is
    longer than ``span`` (what a sample spans: a delay of 1.0, a stream; ``what`` names it in
    the message, ``hint`` adds its size and the usual ticks), or so short that the span holds
    more than :data:`MAX_WINDOW_TICKS` ticks."""
    name = f"tick_{unit}"
    rule = Range(0, span, "nanoseconds" if unit == "ns" else "microseconds", low_open=True)
    if not rule.accepts(tick):
        raise ConfigError(f"{name}={shown(tick)}: expected {rule.expected()} ({hint})")
    if span / tick > MAX_WINDOW_TICKS:
        raise ConfigError(
            f"{name}={tick!r}: {what} would span {span / tick:.3g} ticks; expected at most "
            f"2**53 ({name} >= {span / MAX_WINDOW_TICKS:.3g})"
        )


def _check_tick(unit_ns: float, tick_ns: float) -> None:
    """Refuse a tick that is not a positive number, is longer than a delay of 1.0 (every event
    of the window would then fall in its first tick or two), or so short that the window spans
    more than :data:`MAX_WINDOW_TICKS`."""
    unit = Range(0, None, "nanoseconds", low_open=True, finite=True)
    if not unit.accepts(unit_ns):
        raise ConfigError(f"unit_ns={unit_ns!r}: expected {unit.expected()}")
    hint = f"a delay of 1.0 is {unit_ns:g} ns; tick_ns=1 gives nanoseconds, 1000 microseconds"
    check_tick(tick_ns, unit_ns, "ns", f"the {unit_ns:g} ns window", hint)


def window_ticks(unit_ns: float, tick_ns: float = TICK_NS) -> int:
    """Ticks that events' times can take: every event of a delay in [0, 1] has
    0 <= t < ``window_ticks`` (t rounds, and a delay of 1.0 is ``round(unit_ns / tick_ns)``).
    Frames of a fixed time span from 0 to it are the same for every sample
    (docs/loading.md)."""
    _check_tick(unit_ns, tick_ns)
    return round(unit_ns / tick_ns) + 1


def to_events(
    delays: np.ndarray, unit_ns: float, no_return: float = 1.0, tick_ns: float = TICK_NS
) -> np.ndarray:
    """One sample as spike events in Tonic's convention, sorted by time.

    delays : (H, W) normalised delays of one sample
    unit_ns : nanoseconds of a delay of 1.0: :func:`delay_unit_ns` of the split's attributes
        (``tof_max_ns``, 667.13 ns for 100 m, under flash timing; the sweep window under scan
        timing)
    no_return : delays at or above it are no event; pass :func:`spike_threshold` of the split's
        attributes (inf for the paper profile, where every pixel is a pulse)
    tick_ns : nanoseconds of one unit of ``t``: 1000 (microseconds, Tonic's unit) by default;
        a flash window (667 ns) needs a finer one, e.g. 1 (nanoseconds); at most ``unit_ns``
    returns : (E,) :data:`EVENT_DTYPE` array with fields x (column), y (row),
        t = round(delay * unit_ns / tick_ns) (the arrival time in ticks) and p = 0 (the one
        polarity of ``sensor_size``: a pulse). A pulse at the no-return value (the end of the
        window) is no event.
    """
    _check_tick(unit_ns, tick_ns)
    delays = np.asarray(delays)
    rows, cols = np.nonzero(delays < no_return)
    t = np.round(delays[rows, cols].astype(np.float64) * (unit_ns / tick_ns)).astype(np.int64)
    order = np.argsort(t, kind="stable")
    events = np.zeros(len(t), EVENT_DTYPE)
    events["x"], events["y"], events["t"] = cols[order], rows[order], t[order]
    return events


def _event_unit_ns(info: SplitInfo) -> float:
    """Nanoseconds of a delay of 1.0 for events: :func:`delay_unit_ns`, or a DVS split's
    ``time_window_us``."""
    unit = delay_unit_ns(info.attrs)
    if unit is None and "time_window_us" in info.attrs:
        unit = 1000.0 * float(info.attrs["time_window_us"])
    if unit is None:
        raise DatasetError(
            f"{info.path}: no time unit of the delays (attribute delay_unit_ns, tof_max_ns or "
            "time_window_us); expected one to make events"
        )
    return unit


class EventDataset(_SplitRows):
    """One split as spike events, a dataset in the manner of ``tonic.datasets``: sample
    ``i`` is (:func:`to_events` of its delays, label), with the split's own time unit
    (:func:`delay_unit_ns`; a DVS split's ``time_window_us``) and no-return rule
    (:func:`spike_threshold`). Needs no torch; a ``DataLoader`` takes it (with
    ``num_workers > 0``: files are opened lazily in each worker).

    tick_ns : nanoseconds of one unit of an event's ``t`` (default: 1000, microseconds,
        Tonic's unit, where the split's window is at least that long; else 1, nanoseconds, as
        for the 667 ns window of flash timing), at most the split's unit and at least
        1 / :data:`MAX_WINDOW_TICKS` of it
    transform : optional callable applied to the events (a Tonic transform, e.g. ``ToFrame``)
    target_transform : optional callable applied to the label (an int)
    field : "delays" (with noise, the default) or "clean_delays"

    Attributes as Tonic's datasets have them: ``sensor_size`` (W, H, 1), ``dtype``
    (:data:`EVENT_DTYPE`), ``ordering`` ("x", "y", "t", "p"), ``classes`` (the class names);
    and ``tick_ns``, ``unit_ns``, ``window_ticks`` (every event has 0 <= t < it).
    """

    dtype = EVENT_DTYPE
    ordering = EVENT_DTYPE.names

    def __init__(
        self,
        path: str | Path,
        split: str = "train",
        transform=None,
        target_transform=None,
        tick_ns: float | None = None,
        field: str = "delays",
    ):
        super().__init__(path, split, field)
        self.unit_ns = _event_unit_ns(self.info)
        if tick_ns is None:  # a microsecond where the window holds one, else a nanosecond
            tick_ns = TICK_NS if self.unit_ns >= TICK_NS else 1.0
        self.window_ticks = window_ticks(self.unit_ns, tick_ns)
        self.tick_ns = tick_ns
        self.no_return = spike_threshold(self.info.attrs)
        self.sensor_size = sensor_size(self.info.width, self.info.height)
        self.transform = transform
        self.target_transform = target_transform

    def __getitem__(self, index: int):
        delays, label = self._row(index)
        events = to_events(delays, self.unit_ns, self.no_return, self.tick_ns)
        if self.transform is not None:
            events = self.transform(events)
        if self.target_transform is not None:
            label = self.target_transform(label)
        return events, label
