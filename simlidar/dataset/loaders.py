"""Loading simlidar datasets: numpy arrays, a torch ``Dataset``, and spike events.

Examples (tested) are in ``docs/loading.md``.
"""

from pathlib import Path

import h5py
import numpy as np

from simlidar.dataset.reader import load_arrays, read_split_info
from simlidar.errors import DatasetError

EVENT_DTYPE = np.dtype([("x", np.int64), ("y", np.int64), ("t", np.int64), ("p", np.int64)])


def split_path(path: str | Path, split: str) -> Path:
    """The file of ``split`` in the dataset directory ``path`` (checked to be a split)."""
    if split not in ("train", "test"):
        raise DatasetError(f"split {split!r}: expected 'train' or 'test'")
    file = Path(path) / f"{split}.h5"
    if not file.is_file():
        raise DatasetError(f"{path}: expected a dataset directory with {split}.h5")
    read_split_info(file)  # schema and version checks
    return file


def load_split(path: str | Path, split: str = "train", field: str = "delays"):
    """A whole split as numpy arrays.

    returns : x (N, H, W) float32 (``field``: "delays" with noise, or "clean_delays" of a
        generated dataset; H = 16 there), y (N,) int64 class labels
    """
    arrays = load_arrays(split_path(path, split), (field, "labels"))
    return arrays[field], arrays["labels"]


class _PulseSplit:
    """A ``torch.utils.data.Dataset`` over one split: (delays as a float tensor, label).

    The HDF5 file is opened lazily, once in each process that reads from it, so a
    ``DataLoader`` with ``num_workers > 0`` works (h5py handles do not survive a fork).

    transform : optional callable applied to the (H, W) float tensor
    field : "delays" (with noise, the default) or "clean_delays"
    """

    def __init__(
        self, path: str | Path, split: str = "train", transform=None, field: str = "delays"
    ):
        self.file = split_path(path, split)
        self.field = field
        self.transform = transform
        self.size = read_split_info(self.file).size
        self._h5 = None

    def __len__(self) -> int:
        return self.size

    def __getitem__(self, index: int):
        import torch

        if not -self.size <= index < self.size:
            raise IndexError(f"index {index} out of range for {self.size} samples")
        if self._h5 is None:
            self._h5 = h5py.File(self.file, "r")
        x = torch.from_numpy(self._h5[self.field][index])
        if self.transform is not None:
            x = self.transform(x)
        return x, int(self._h5["labels"][index])

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state["_h5"] = None  # each worker opens its own handle
        return state

    def __del__(self) -> None:
        if getattr(self, "_h5", None) is not None:
            self._h5.close()


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


def sensor_size(width: int, height: int = 16) -> tuple[int, int, int]:
    """Tonic's ``sensor_size`` of a sample: (W columns, H rows, 1 polarity)."""
    return (width, height, 1)


def to_events(delays: np.ndarray, tof_max_ns: float, no_return: float = 1.0) -> np.ndarray:
    """One sample as spike events in the Tonic convention, sorted by time.

    delays : (H, W) normalised delays of one sample
    tof_max_ns : the split's ``tof_max_ns`` attribute (667.13 ns for 100 m)
    no_return : delays at or above it are no event; pass :func:`spike_threshold` of the split's
        attributes (inf for the paper profile, where every pixel is a pulse)
    returns : structured array with fields x (column), y (row), t (arrival time in
        picoseconds, so the 2 mm range step of 13 ps survives), p (always 1: a pulse).
        A pulse at the no-return value (the end of the window) is no event.
    """
    delays = np.asarray(delays)
    rows, cols = np.nonzero(delays < no_return)
    t = np.round(delays[rows, cols].astype(np.float64) * tof_max_ns * 1000.0).astype(np.int64)
    order = np.argsort(t, kind="stable")
    events = np.empty(len(t), EVENT_DTYPE)
    events["x"], events["y"], events["t"] = cols[order], rows[order], t[order]
    events["p"] = 1
    return events
