"""Reading split files: the schema and version checks every reader goes through."""

import json
import warnings
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from simlidar.dataset.schema import REQUIRED_ATTRS, SPLITS, split_source
from simlidar.dataset.version import GENERATOR, PHYSICAL_VERSION, SOURCES, major
from simlidar.errors import DatasetError


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
