"""Reading split files: the schema and version checks every reader goes through."""

import json
import warnings
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from simlidar.dataset.schema import REQUIRED_ATTRS, SPLITS, split_source
from simlidar.dataset.shards import find_split_files, shard_of
from simlidar.dataset.version import GENERATOR, PHYSICAL_VERSION, SCAN_VERSION, SOURCES, major
from simlidar.errors import DatasetError


@dataclass(frozen=True)
class SplitInfo:
    path: Path  # the split's (first) file
    size: int  # samples in all its files
    width: int
    attrs: dict  # JSON attributes decoded (of the first file; a shard's own are left out)
    height: int = 16  # rows H of a sample
    files: tuple[Path, ...] = ()  # every file of the split, in sample order (default: path)
    sizes: tuple[int, ...] = ()  # samples in each file

    def __post_init__(self):
        if not self.files:
            object.__setattr__(self, "files", (self.path,))
            object.__setattr__(self, "sizes", (self.size,))

    @property
    def source(self) -> str:
        return self.attrs.get("source", GENERATOR)

    @property
    def sharded(self) -> bool:
        """Whether the split is written as shard files (``train-00000-of-00004.h5``, ...)."""
        return shard_of(self.files[0].name) is not None

    @property
    def nbytes(self) -> int:
        """The size of the split's files on disk."""
        return sum(f.stat().st_size for f in self.files)

    def read(self, names: tuple[str, ...], rows=slice(None)) -> dict[str, np.ndarray]:
        """Datasets ``names`` of the whole split (all rows, or ``rows``: a slice or sorted
        indices into the split), across its files."""
        return read_rows(self.files, self.sizes, names, rows)


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
    current version: a scan-timed split is SCAN_VERSION (3.0.0); a generated split without a
    profile follows the physical rule, still written as PHYSICAL_VERSION (1.0.0)."""
    if split_source(attrs) != GENERATOR:
        return None
    if _decode(attrs.get("timing", "flash")) == "scan":
        return SCAN_VERSION
    return PHYSICAL_VERSION if "profile" not in attrs else None


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


_SHARD_ATTRS = ("shard", "shards")  # a shard file's own attributes (docs/dataset-format.md)


def read_split(path: str | Path, split: str) -> SplitInfo:
    """The split ``split`` of the dataset directory ``path``, one file or sharded (every shard
    checked: the schema, its index and count, the same attributes and sample shape as the
    first); DatasetError naming the file otherwise."""
    path = Path(path)
    files = find_split_files(path, split)
    if not files:
        raise DatasetError(f"{path}: expected a dataset directory with {split}.h5")
    infos = [read_split_info(f) for f in files]
    first = infos[0]
    if len(files) == 1 and first.attrs.get("shards") is None:
        return first
    common = {k: v for k, v in first.attrs.items() if k not in _SHARD_ATTRS}
    for index, info in enumerate(infos):
        if (info.attrs.get("shard"), info.attrs.get("shards")) != (index, len(files)):
            raise DatasetError(
                f"{info.path}: attributes shard={info.attrs.get('shard')!r}, "
                f"shards={info.attrs.get('shards')!r}; expected {index} and {len(files)} "
                "(renamed shard files?)"
            )
        own = {k: v for k, v in info.attrs.items() if k not in _SHARD_ATTRS}
        if own != common or (info.height, info.width) != (first.height, first.width):
            raise DatasetError(
                f"{info.path}: attributes or sample shape differ from {first.path.name}'s; "
                "expected the shards of one split"
            )
    return SplitInfo(
        first.path,
        sum(i.size for i in infos),
        first.width,
        common,
        first.height,
        tuple(files),
        tuple(i.size for i in infos),
    )


def dataset_splits(path: str | Path) -> dict[str, SplitInfo]:
    """The splits of a dataset directory; raises DatasetError if it is not one."""
    path = Path(path)
    if not path.is_dir():
        raise DatasetError(f"{path}: expected a dataset directory with train.h5 and test.h5")
    absent = [f"{s}.h5" for s in SPLITS if not find_split_files(path, s)]
    if absent:
        raise DatasetError(
            f"{path}: not a simlidar dataset (missing {', '.join(absent)}; expected train.h5 "
            "and test.h5)"
        )
    return {s: read_split(path, s) for s in SPLITS}


def load_arrays(path: Path, names: tuple[str, ...], rows=slice(None)) -> dict[str, np.ndarray]:
    """Read some datasets (all rows by default) of one split file."""
    with h5py.File(path, "r") as f:
        return {n: f[n][rows] for n in names}


def read_rows(files, sizes, names: tuple[str, ...], rows=slice(None)) -> dict[str, np.ndarray]:
    """Datasets ``names`` of a split written as ``files`` of ``sizes`` samples each: all rows,
    a slice, or sorted row indices into the whole split, concatenated in sample order."""
    if len(files) == 1:
        return load_arrays(files[0], names, rows)
    total = sum(sizes)
    wanted = np.arange(total)[rows] if isinstance(rows, slice) else np.asarray(rows)
    if not len(wanted):
        return load_arrays(files[0], names, slice(0, 0))
    starts = np.concatenate([[0], np.cumsum(sizes)])
    parts: dict[str, list] = {n: [] for n in names}
    for file, start, stop in zip(files, starts[:-1], starts[1:]):
        mine = wanted[(wanted >= start) & (wanted < stop)] - start
        if not len(mine):
            continue
        if isinstance(rows, slice) and len(mine) == stop - start:
            mine = slice(None)  # the whole file: one contiguous read
        for name, values in load_arrays(file, names, mine).items():
            parts[name].append(values)
    return {n: np.concatenate(v) for n, v in parts.items()}
