"""HDF5 split files: the schema, a streaming writer, and a checked reader.

Every dataset and attribute is described in ``docs/dataset-format.md``; keep the two in step.
Files are written deterministically: no timestamps, fixed chunking, gzip (level 1), shuffle
where it pays.
Level 1 because the noisy delays barely compress and higher levels cost time for ~1 %.
"""

import json
import warnings
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from simlidar.dataset.version import DATASET_VERSION, RELEASE_NOTES, major
from simlidar.errors import DatasetError
from simlidar.pulses import add_noise
from simlidar.simulate import Samples

CHUNK_SAMPLES = 256
SPLITS = ("train", "test")

# name -> (dtype, trailing shape given W, Samples field or None for the noisy delays)
SCHEMA: dict[str, tuple[str, object, str | None]] = {
    "delays": ("float32", lambda w: (16, w), None),
    "clean_delays": ("float32", lambda w: (16, w), "clean_delays"),
    "tof_ns": ("float32", lambda w: (16, w), "tof_ns"),
    "surface": ("uint8", lambda w: (16, w), "surface"),
    "labels": ("int64", lambda w: (), "labels"),
    "layout": ("uint8", lambda w: (), "layout"),
    "object": ("uint8", lambda w: (), "object"),
    "object_pose": ("float32", lambda w: (3,), "object_pose"),
    "object_hits": ("int32", lambda w: (), "object_hits"),
    "attempts": ("int32", lambda w: (), "attempts"),
    "phase": ("float32", lambda w: (), "phase"),
    "shift": ("float32", lambda w: (), "shift"),
}
# The shuffle filter helps gzip on the noisy delays (random mantissas) and hurts it on the
# quantised clean delays and times of flight (measured: smaller and faster without it).
SHUFFLED = {"delays", "phase", "shift", "object_pose"}
REQUIRED_ATTRS = ("dataset_version", "simlidar_version", "config", "seed", "noise", "split",
                  "class_names", "class_mode", "sensor")  # fmt: skip


class SplitWriter:
    """Appends blocks of samples to one split file; peak memory is a block plus one chunk.

    Rows are written one whole chunk at a time, every dataset in turn, so the file's layout
    (and therefore its bytes) does not depend on the size of the blocks handed in.
    """

    def __init__(self, path: Path, size: int, width: int, noise: float, attrs: dict):
        self.noise = noise
        self.size = size
        self.chunk = min(CHUNK_SAMPLES, size)
        self.written = 0
        self.pending: dict[str, list[np.ndarray]] = {name: [] for name in SCHEMA}
        self.file = h5py.File(path, "w", libver=("earliest", "v110"), track_order=False)
        for name, (dtype, tail, _) in SCHEMA.items():
            shape = (size, *tail(width))
            self.file.create_dataset(
                name, shape=shape, dtype=dtype, chunks=(self.chunk, *shape[1:]),
                compression="gzip", compression_opts=1, shuffle=name in SHUFFLED,
                track_times=False,
            )  # fmt: skip
        for key, value in attrs.items():
            self.file.attrs[key] = value

    def append(self, samples: Samples) -> None:
        """Add the next block of samples (in split order)."""
        for name, (_, _, source) in SCHEMA.items():
            if source is None:
                value = add_noise(samples.clean_delays, self.noise, samples.noise_u)
            else:
                value = getattr(samples, source)
            self.pending[name].append(value)
        ready = sum(len(v) for v in self.pending["labels"])
        while ready >= self.chunk or (ready and self.written + ready == self.size):
            rows = min(self.chunk, ready)
            for name, parts in self.pending.items():
                block = np.concatenate(parts)
                self.file[name][self.written : self.written + rows] = block[:rows]
                self.pending[name] = [block[rows:]]
            self.written += rows
            ready -= rows

    def close(self) -> None:
        if self.written != self.size:
            self.file.close()
            raise RuntimeError(f"{self.file.filename}: {self.written} of {self.size} rows")
        self.file.close()


@dataclass(frozen=True)
class SplitInfo:
    path: Path
    size: int
    width: int
    attrs: dict  # JSON attributes decoded


def _decode(value):
    if isinstance(value, bytes):
        value = value.decode()
    if isinstance(value, str) and value[:1] in "{[":
        return json.loads(value)
    if isinstance(value, np.ndarray):
        return [_decode(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value  # str, int, float


def read_split_info(path: Path) -> SplitInfo:
    """Open a split file and check it carries the simlidar schema."""
    try:
        with h5py.File(path, "r") as f:
            missing = [k for k in REQUIRED_ATTRS if k not in f.attrs]
            missing += [k for k in ("delays", "labels") if k not in f]
            if missing:
                raise DatasetError(f"{path}: not a simlidar split (missing {', '.join(missing)})")
            if f["delays"].ndim != 3:
                raise DatasetError(f"{path}: 'delays' has shape {f['delays'].shape}, expected "
                                   "(N, 16, W)")  # fmt: skip
            attrs = {k: _decode(v) for k, v in f.attrs.items()}
            info = SplitInfo(path, f["delays"].shape[0], f["delays"].shape[2], attrs)
    except OSError as exc:
        raise DatasetError(f"{path}: cannot read as HDF5 ({exc})") from None
    check_version(path, attrs["dataset_version"])
    return info


_warned: set[str] = set()


def check_version(path: Path, version: str) -> None:
    """Refuse a dataset from a newer MAJOR version; warn once about an older one."""
    try:
        theirs, ours = major(version), major(DATASET_VERSION)
    except ValueError:
        raise DatasetError(
            f"{path}: dataset version {version!r}: expected MAJOR.MINOR.PATCH"
        ) from None
    if theirs > ours:
        raise DatasetError(
            f"{path}: dataset version {version} is newer than this simlidar reads "
            f"(MAJOR {ours}); expected a dataset of version {ours}.x.x: upgrade simlidar"
        )
    if theirs < ours and version not in _warned:
        _warned.add(version)
        warnings.warn(
            f"{path}: dataset version {version}, this simlidar writes {DATASET_VERSION} "
            f"(records changed): {RELEASE_NOTES[DATASET_VERSION]}",
            stacklevel=3,
        )


def dataset_splits(path: str | Path) -> dict[str, SplitInfo]:
    """The splits of a dataset directory; raises DatasetError if it is not one."""
    path = Path(path)
    if not path.is_dir():
        raise DatasetError(f"{path}: expected a dataset directory with train.h5 and test.h5")
    files = {s: path / f"{s}.h5" for s in SPLITS}
    absent = [f.name for f in files.values() if not f.is_file()]
    if absent:
        raise DatasetError(
            f"{path}: not a simlidar dataset (missing {', '.join(absent)}; expected train.h5 "
            "and test.h5)"
        )
    return {s: read_split_info(f) for s, f in files.items()}


def load_arrays(path: Path, names: tuple[str, ...], rows=slice(None)) -> dict[str, np.ndarray]:
    """Read some datasets (all rows by default) of one split file."""
    with h5py.File(path, "r") as f:
        return {n: f[n][rows] for n in names}
