"""HDF5 split files: the schemas, a streaming writer, and a checked reader.

Every dataset and attribute is described in ``docs/dataset-format.md`` (the generator's) and
``docs/converters.md`` (converted real data); keep them in step. Files are written
deterministically: no timestamps, fixed chunking, gzip (level 1), shuffle where it pays.
Level 1 because the noisy delays barely compress and higher levels cost time for ~1 %.
"""

import json
import os
import warnings
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from simlidar.dataset.version import GENERATOR, PHYSICAL_VERSION, SOURCES, major
from simlidar.errors import DatasetError
from simlidar.pulses import profile_pulses
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
REQUIRED_ATTRS = (
    "dataset_version",
    "simlidar_version",
    "config",
    "seed",
    "noise",
    "split",
    "class_names",
    "class_mode",
    "sensor",
)

# Converted real data (simlidar.convert), by the split's `source` attribute:
# name -> (dtype, shape), a shape's letters being N samples, E events, H rows, W columns.
CONVERTED_SCHEMAS: dict[str, dict[str, tuple[str, tuple]]] = {
    "kitti": {
        "delays": ("float32", ("N", "H", "W")),
        "labels": ("int64", ("N",)),
        "frame": ("int64", ("N",)),
        "crop_origin": ("int32", ("N", 2)),
        "box_corners_m": ("float32", ("N", 8, 3)),
        "box_points": ("int32", ("N",)),
        "truncated": ("float32", ("N",)),
        "occluded": ("uint8", ("N",)),
    },
    "dvs-barrel": {
        "delays": ("float32", ("N", "H", "W")),
        "labels": ("int64", ("N",)),
        "recording": ("int64", ("N",)),
        "event_start": ("int64", ("N",)),
        "event_count": ("int64", ("N",)),
        "event_x": ("uint8", ("E",)),
        "event_y": ("uint8", ("E",)),
        "event_p": ("int8", ("E",)),
        "event_t_us": ("int64", ("E",)),
    },
}


def split_source(attrs) -> str:
    """The ``source`` of a split from its attributes; the generator's files carry none."""
    return _decode(attrs.get("source", GENERATOR))


def expected_shapes(source: str, n: int, h: int, w: int, e: int = 0) -> dict[str, tuple]:
    """name -> (dtype, full shape) of every dataset a split of ``source`` must hold."""
    if source == GENERATOR:
        return {name: (dtype, (n, *tail(w))) for name, (dtype, tail, _) in SCHEMA.items()}
    if source not in CONVERTED_SCHEMAS:
        known = ", ".join([GENERATOR, *CONVERTED_SCHEMAS])
        raise DatasetError(f"source {source!r}: expected one of {known}")
    dims = {"N": n, "E": e, "H": h, "W": w}
    return {
        name: (dtype, tuple(dims.get(d, d) for d in shape))
        for name, (dtype, shape) in CONVERTED_SCHEMAS[source].items()
    }


class RowWriter:
    """Appends blocks of rows to the datasets of one HDF5 file; peak memory is a block plus
    one chunk.

    shapes : name -> (dtype, trailing shape); every dataset gets ``size`` rows
    Rows are written one whole chunk at a time, every dataset in turn, so the file's layout
    (and therefore its bytes) does not depend on the size of the blocks handed in.

    Write errors (a full disk) surface at the write that failed, as a DatasetError naming the
    file and the cause: HDF5's chunk cache is off (``rdcc_nbytes=0``; whole chunks are
    written, so it saved nothing, and the bytes are the same), and the dataset handles are
    held open. With the cache on, a failed write surfaced only when a cached chunk was evicted
    inside a handle's deallocation, where h5py can only print it: generation went on for
    seconds, printing thousands of tracebacks, and crashed at close. After an error,
    :meth:`abort` closes the file without raising.
    """

    def __init__(
        self,
        path: Path,
        size: int,
        shapes: dict[str, tuple[str, tuple]],
        attrs: dict,
        shuffled: frozenset[str] = frozenset(),
    ):
        self.size = size
        self.chunk = min(CHUNK_SAMPLES, size)
        self.written = 0
        self.pending: dict[str, list[np.ndarray]] = {name: [] for name in shapes}
        self.path = Path(path)
        self.file = h5py.File(
            path, "w", libver=("earliest", "v110"), track_order=False, rdcc_nbytes=0
        )
        self.datasets = {}
        for name, (dtype, tail) in shapes.items():
            shape = (size, *tail)
            self.datasets[name] = self.file.create_dataset(
                name,
                shape=shape,
                dtype=dtype,
                chunks=(self.chunk, *shape[1:]),
                compression="gzip",
                compression_opts=1,
                shuffle=name in shuffled,
                track_times=False,
            )
        for key, value in attrs.items():
            self.file.attrs[key] = value

    def append(self, block: dict[str, np.ndarray]) -> None:
        """Add the next rows (in file order): one array per dataset, equally long."""
        for name in self.pending:
            self.pending[name].append(block[name])
        first = next(iter(self.pending))
        ready = sum(len(v) for v in self.pending[first])
        while ready >= self.chunk or (ready and self.written + ready == self.size):
            rows = min(self.chunk, ready)
            for name, parts in self.pending.items():
                block = np.concatenate(parts)
                with self._failing():
                    self.datasets[name][self.written : self.written + rows] = block[:rows]
                self.pending[name] = [block[rows:]]
            self.written += rows
            ready -= rows

    def add_rows(self, name: str, values: np.ndarray, dtype: str, chunk: int = 65_536) -> None:
        """A whole dataset with its own number of rows (e.g. one per event), written at once."""
        values = np.asarray(values, dtype=dtype)
        if not len(values):  # HDF5 has no chunks for an empty dataset
            self.file.create_dataset(name, data=values, track_times=False)
            return
        self.file.create_dataset(
            name,
            data=values,
            chunks=(min(chunk, len(values)),),
            compression="gzip",
            compression_opts=1,
            shuffle=True,
            track_times=False,
        )

    @contextmanager
    def _failing(self):
        """Turn an HDF5 write error into one DatasetError naming the file and the cause."""
        try:
            yield
        except (OSError, RuntimeError) as exc:
            code = getattr(exc, "errno", None)
            cause = os.strerror(code) if code else str(exc).splitlines()[0]
            raise DatasetError(f"{self.path}: cannot write ({cause})") from None

    def close(self) -> None:
        if self.written != self.size:
            self.abort()
            raise RuntimeError(f"{self.path}: {self.written} of {self.size} rows")
        self.datasets = {}
        with self._failing():
            self.file.close()

    def abort(self) -> None:
        """Close after an error, never raising (what is in the file no longer matters)."""
        self.datasets = {}
        try:
            self.file.close()
        except Exception:  # noqa: BLE001 - a failed flush of a file about to be deleted
            pass


class SplitWriter(RowWriter):
    """Appends blocks of generated samples to one split file (the generator's schema).

    rule : the profile's pulse rule (``GeneratorConfig.pulse_rule``): what a missing return is
        written as and which pixels get the noise; ``clean_delays`` are written under the rule
        too (missing returns at ``missing_delay``), before noise
    """

    def __init__(self, path: Path, size: int, width: int, noise: float, attrs: dict, rule: dict):
        self.noise = noise
        self.rule = rule
        shapes = {name: (dtype, tail(width)) for name, (dtype, tail, _) in SCHEMA.items()}
        super().__init__(path, size, shapes, attrs, frozenset(SHUFFLED))

    def append(self, samples: Samples) -> None:
        """Add the next block of samples (in split order)."""
        rule = self.rule
        clean, noisy = profile_pulses(
            samples.clean_delays,
            self.noise,
            samples.noise_u,
            rule["missing_delay"],
            rule["noise_on"],
        )
        block = {}
        for name, (_, _, source) in SCHEMA.items():
            if source is None:
                block[name] = noisy
            elif source == "clean_delays":
                block[name] = clean
            else:
                block[name] = getattr(samples, source)
        super().append(block)


@dataclass(frozen=True)
class SplitInfo:
    path: Path
    size: int
    width: int
    attrs: dict  # JSON attributes decoded
    height: int = 16  # rows H of a sample

    @property
    def source(self) -> str:
        return self.attrs.get("source", GENERATOR)


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
                raise DatasetError(
                    f"{path}: 'delays' has shape {f['delays'].shape}, expected (N, H, W)"
                )
            attrs = {k: _decode(v) for k, v in f.attrs.items()}
            size, height, width = f["delays"].shape
            info = SplitInfo(path, size, width, attrs, height)
    except OSError as exc:
        raise DatasetError(f"{path}: cannot read as HDF5 ({exc})") from None
    check_version(path, attrs["dataset_version"], info.source, written_version(attrs))
    return info


def written_version(attrs) -> str | None:
    """The version this simlidar writes for a split like this one, when it is not its source's
    current version: a generated split without a profile follows the physical rule, still
    written as PHYSICAL_VERSION (1.0.0)."""
    physical = split_source(attrs) == GENERATOR and "profile" not in attrs
    return PHYSICAL_VERSION if physical else None


_warned: set[tuple[str, str]] = set()


def check_version(
    path: Path, version: str, source: str = GENERATOR, writes: str | None = None
) -> None:
    """Refuse a dataset from a newer MAJOR version; warn once about an older one.

    source : the split's ``source``; each source has its own version line
    writes : the version this simlidar writes for such a file, when not the source's current
        one (the generator's physical profile: 1.0.0)
    """
    if source not in SOURCES:
        known = ", ".join(SOURCES)
        raise DatasetError(f"{path}: source {source!r}: expected one of {known}")
    current, _, notes = SOURCES[source]
    current = writes or current
    try:
        theirs, ours = major(version), major(current)
    except ValueError:
        raise DatasetError(
            f"{path}: dataset version {version!r}: expected MAJOR.MINOR.PATCH"
        ) from None
    if theirs > ours:
        raise DatasetError(
            f"{path}: dataset version {version} is newer than this simlidar reads "
            f"(MAJOR {ours}); expected a dataset of version {ours}.x.x: upgrade simlidar"
        )
    if theirs < ours and (source, version) not in _warned:
        _warned.add((source, version))
        warnings.warn(
            f"{path}: dataset version {version}, this simlidar writes {current} "
            f"(records changed): {notes[current]}",
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
