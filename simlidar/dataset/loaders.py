"""Loading simlidar datasets: numpy arrays, a torch ``Dataset``, and spike events.

Examples (tested) are in ``docs/loading.md``.
"""

from pathlib import Path

import h5py
import numpy as np

from simlidar.dataset.reader import SplitInfo, read_split, value_problems
from simlidar.dataset.schema import WAVEFORM_SCHEMA, generated_schema
from simlidar.errors import ConfigError, DatasetError, shown
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


class _SplitRows:
    """One split's samples read by index: (delays (H, W) float32 numpy, label).

    The HDF5 files (one, or the split's shards) are opened lazily, once in each process that
    reads from them, so a ``DataLoader`` with ``num_workers > 0`` works (h5py handles do not
    survive a fork).
    """

    def __init__(self, path: str | Path, split: str, field: str):
        info = _field_checked(split_info(path, split), field)
        self.info = info
        self.files = info.files
        self.starts = np.cumsum((0, *info.sizes))  # the first sample of each file
        self.field = field
        self.size = info.size
        self._h5 = None  # open files, by position in self.files

    def __len__(self) -> int:
        return self.size

    def _row(self, index: int) -> tuple[np.ndarray, int]:
        if not -self.size <= index < self.size:
            raise IndexError(f"index {index} out of range for {self.size} samples")
        index %= self.size
        part = int(np.searchsorted(self.starts, index, side="right")) - 1
        if self._h5 is None:
            self._h5 = {}
        if part not in self._h5:
            self._h5[part] = h5py.File(self.files[part], "r")
        f, row = self._h5[part], index - int(self.starts[part])
        delays, label = f[self.field][row], f["labels"][row]
        where = f"{self.files[part]} (sample {row})"
        _check_values(where, self.info.attrs, {self.field: delays, "labels": label})
        return delays, int(label)

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state["_h5"] = None  # each worker opens its own handle
        return state

    def __del__(self) -> None:
        for f in (getattr(self, "_h5", None) or {}).values():
            try:
                f.close()
            except Exception:  # h5py half torn down at interpreter exit
                pass


class _PulseSplit(_SplitRows):
    """A ``torch.utils.data.Dataset`` over one split: (delays as a float tensor, label).

    Files are opened lazily in each worker process, so ``num_workers > 0`` works.

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


def _check_tick(unit_ns: float, tick_ns: float) -> None:
    """Refuse a tick that is not a positive number, is longer than a delay of 1.0 (every event
    of the window would then fall in its first tick or two), or so short that the window spans
    more than :data:`MAX_WINDOW_TICKS`."""
    unit = Range(0, None, "nanoseconds", low_open=True, finite=True)
    if not unit.accepts(unit_ns):
        raise ConfigError(f"unit_ns={unit_ns!r}: expected {unit.expected()}")
    tick = Range(0, unit_ns, "nanoseconds", low_open=True)
    if not tick.accepts(tick_ns):
        raise ConfigError(
            f"tick_ns={tick_ns!r}: expected {tick.expected()} (a delay of 1.0 is "
            f"{unit_ns:g} ns; tick_ns=1 gives nanoseconds, 1000 microseconds)"
        )
    if unit_ns / tick_ns > MAX_WINDOW_TICKS:
        raise ConfigError(
            f"tick_ns={tick_ns!r}: the {unit_ns:g} ns window would span {unit_ns / tick_ns:.3g} "
            f"ticks; expected at most 2**53 (tick_ns >= {unit_ns / MAX_WINDOW_TICKS:.3g})"
        )


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
        self.classes = list(self.info.attrs["class_names"])
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
