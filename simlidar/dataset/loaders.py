"""Loading simlidar datasets: numpy arrays, a torch ``Dataset``, and spike events.

Examples (tested) are in ``docs/loading.md``.
"""

from pathlib import Path

import h5py
import numpy as np

from simlidar.dataset.reader import SplitInfo, read_split
from simlidar.errors import DatasetError

EVENT_DTYPE = np.dtype([("x", np.int64), ("y", np.int64), ("t", np.int64), ("p", np.int64)])


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
        generated dataset; H = 16 there), y (N,) int64 class labels
    """
    arrays = split_info(path, split).read((field, "labels"))
    return arrays[field], arrays["labels"]


class _PulseSplit:
    """A ``torch.utils.data.Dataset`` over one split: (delays as a float tensor, label).

    The HDF5 files (one, or the split's shards) are opened lazily, once in each process that
    reads from them, so a ``DataLoader`` with ``num_workers > 0`` works (h5py handles do not
    survive a fork).

    transform : optional callable applied to the (H, W) float tensor
    field : "delays" (with noise, the default) or "clean_delays"
    """

    def __init__(
        self, path: str | Path, split: str = "train", transform=None, field: str = "delays"
    ):
        info = split_info(path, split)
        self.files = info.files
        self.starts = np.cumsum((0, *info.sizes))  # the first sample of each file
        self.field = field
        self.transform = transform
        self.size = info.size
        self._h5 = None  # open files, by position in self.files

    def __len__(self) -> int:
        return self.size

    def __getitem__(self, index: int):
        import torch

        if not -self.size <= index < self.size:
            raise IndexError(f"index {index} out of range for {self.size} samples")
        index %= self.size
        part = int(np.searchsorted(self.starts, index, side="right")) - 1
        if self._h5 is None:
            self._h5 = {}
        if part not in self._h5:
            self._h5[part] = h5py.File(self.files[part], "r")
        f, row = self._h5[part], index - int(self.starts[part])
        x = torch.from_numpy(f[self.field][row])
        if self.transform is not None:
            x = self.transform(x)
        return x, int(f["labels"][row])

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state["_h5"] = None  # each worker opens its own handle
        return state

    def __del__(self) -> None:
        for f in (getattr(self, "_h5", None) or {}).values():
            try:
                f.close()
            except Exception:  # noqa: BLE001 - h5py half torn down at interpreter exit
                pass


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


def sensor_size(width: int, height: int = 16) -> tuple[int, int, int]:
    """Tonic's ``sensor_size`` of a sample: (W columns, H rows, 1 polarity)."""
    return (width, height, 1)


def to_events(delays: np.ndarray, unit_ns: float, no_return: float = 1.0) -> np.ndarray:
    """One sample as spike events in the Tonic convention, sorted by time.

    delays : (H, W) normalised delays of one sample
    unit_ns : nanoseconds of a delay of 1.0: :func:`delay_unit_ns` of the split's attributes
        (``tof_max_ns``, 667.13 ns for 100 m, under flash timing; the sweep window under scan
        timing)
    no_return : delays at or above it are no event; pass :func:`spike_threshold` of the split's
        attributes (inf for the paper profile, where every pixel is a pulse)
    returns : structured array with fields x (column), y (row), t (arrival time in
        picoseconds, so the 2 mm range step of 13 ps survives a flash sample), p (always 1: a
        pulse). A pulse at the no-return value (the end of the window) is no event.
    """
    delays = np.asarray(delays)
    rows, cols = np.nonzero(delays < no_return)
    t = np.round(delays[rows, cols].astype(np.float64) * unit_ns * 1000.0).astype(np.int64)
    order = np.argsort(t, kind="stable")
    events = np.empty(len(t), EVENT_DTYPE)
    events["x"], events["y"], events["t"] = cols[order], rows[order], t[order]
    events["p"] = 1
    return events
