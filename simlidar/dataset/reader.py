"""Reading split files: the schema and version checks every reader goes through."""

import json
import math
import os
import stat
import warnings
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from simlidar.content import file_kind
from simlidar.dataset.schema import (
    ATTRIBUTES,
    CONVERTED_SCHEMAS,
    REQUIRED_ATTRS,
    SOURCE_ATTRS,
    SPLITS,
    generated_schema,
    split_source,
)
from simlidar.dataset.shards import find_split_files, shard_of
from simlidar.dataset.version import (
    GENERATOR,
    PHYSICAL_VERSION,
    RAIN_WAVEFORM_VERSION,
    RETURNS_VERSION,
    SCAN_VERSION,
    SENSOR_VERSION,
    SOURCES,
    major,
)
from simlidar.errors import ConfigError, DatasetError, first_line, shown
from simlidar.resources import check_memory, size_text


@dataclass(frozen=True)
class SplitInfo:
    path: Path  # the split's (first) file
    size: int  # samples in all its files
    width: int
    attrs: dict  # JSON attributes decoded (of the first file; a shard's own are left out)
    height: int  # rows H of a sample
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
    """An attribute's value as plain Python: str, int, float, lists (arrays), dicts (JSON in a
    string). Never raises: a string that is not JSON stays a string, bytes that are not UTF-8
    stay bytes, for the rules (:data:`~simlidar.dataset.schema.ATTRIBUTES`) to refuse."""
    if isinstance(value, bytes):
        try:
            value = value.decode()
        except UnicodeDecodeError:
            return value
    if isinstance(value, str) and value[:1] in "{[":
        try:
            return json.loads(value)
        except (ValueError, RecursionError):  # not JSON, or nested too deeply
            return value
    if isinstance(value, np.ndarray):
        return _decode(value.item()) if value.ndim == 0 else [_decode(v) for v in value]
    if isinstance(value, np.generic):
        return _decode(value.item())
    return value  # str, int, float, or something no rule accepts (h5py.Empty, ...)


def read_attrs(f: h5py.File) -> tuple[dict, list[str]]:
    """The decoded attributes of an open split file, and the problems of those that cannot be
    read at all (a type h5py cannot convert)."""
    attrs, problems = {}, []
    try:
        names = list(f.attrs)
    except (OSError, RuntimeError, ValueError, TypeError) as exc:
        return {}, [f"{f.filename}: attributes unreadable ({first_line(exc)})"]
    for name in names:
        try:
            attrs[name] = _decode(f.attrs[name])
        except (OSError, RuntimeError, ValueError, TypeError) as exc:
            problems.append(f"{f.filename}: attribute {name!r} unreadable ({first_line(exc)})")
    return attrs, problems


def check_attributes(path: Path, attrs: dict) -> list[str]:
    """The problems of a split's decoded attributes: each one a reader parses
    (:data:`~simlidar.dataset.schema.ATTRIBUTES`) must hold what its rule accepts, the class
    names must be as many as ``classes`` says, and a generated split's ``sensor`` must be a
    sensor. Checked before any reader uses them, so that a hostile or damaged attribute is one
    line naming it, never a traceback."""
    problems, bad = [], set()
    for name in SOURCE_ATTRS.get(
        split_source(attrs) if isinstance(attrs.get("source", ""), str) else "", ()
    ):
        if name not in attrs:
            problems.append(f"{path}: attribute '{name}' missing")
    for name, rule in ATTRIBUTES.items():
        if name in attrs and not rule.accepts(attrs[name]):
            bad.add(name)
            problems.append(
                f"{path}: attribute '{name}' is {shown(attrs[name])}; expected {rule.expected()}"
            )
    names, classes = attrs.get("class_names"), attrs.get("classes")
    if not {"class_names", "classes"} & bad and names is not None and classes is not None:
        if len(names) != classes:
            problems.append(f"{path}: {len(names)} class_names for {classes} classes")
    if not {"sensor", "source"} & bad and "sensor" in attrs and split_source(attrs) == GENERATOR:
        from simlidar.sensor.model import Sensor

        try:
            Sensor.from_dict(attrs["sensor"])
        except ConfigError as exc:
            problems.append(f"{path}: attribute 'sensor': {exc}")
    if "receiver" in attrs and split_source(attrs) == GENERATOR:
        problems += _receiver_problems(path, attrs, bad)
    waveform = [name for name in ("waveform_bin_ns", "waveform_bins") if name in attrs]
    if waveform and (len(waveform) == 1 or "return_mode" not in attrs):
        problems.append(
            f"{path}: attribute(s) {waveform}: expected 'waveform_bin_ns' and 'waveform_bins' "
            "together, in a split whose returns come from waveforms ('return_mode')"
        )
    return problems


def _receiver_problems(path: Path, attrs: dict, bad: set) -> list[str]:
    """A generated split with a receiver: its receiver and materials attributes present and
    each what its file would hold (the card and readers use their values)."""
    from simlidar.sensor.receiver import checked_materials, checked_receiver

    problems = [
        f"{path}: attribute '{name}' missing (a split with a receiver holds it)"
        for name in ("receiver_sha256", "materials", "materials_sha256")
        if name not in attrs
    ]
    if "receiver" not in bad:
        given = {k: v for k, v in attrs["receiver"].items() if k != "name"}
        try:
            checked_receiver("attribute 'receiver'", attrs["receiver"]["name"], given)
        except ConfigError as exc:
            problems.append(f"{path}: {exc}")
    if "materials" in attrs and "materials" not in bad:
        try:
            checked_materials("attribute 'materials'", attrs["materials"])
        except ConfigError as exc:
            problems.append(f"{path}: {exc}")
    return problems


def datasets_of(path: Path, f: h5py.File) -> tuple[dict[str, h5py.Dataset], list[str]]:
    """The datasets of an open split file by name, and the problems of its other members: a
    soft or external link (which would read another file's data) and, under a name the
    schemas use, a group."""
    datasets, problems = {}, []
    names = set(generated_schema("scan", receiver=True, returns=2, waveform_bins=1))
    names |= {n for s in CONVERTED_SCHEMAS.values() for n in s}
    for name in f:
        link = f.get(name, getlink=True)
        if not isinstance(link, h5py.HardLink):
            what = type(link).__name__  # SoftLink, ExternalLink
            problems.append(f"{path}: '{name}' is an HDF5 {what}, expected a dataset in the file")
        elif isinstance(f[name], h5py.Dataset):
            datasets[name] = f[name]
        elif name in names:
            problems.append(f"{path}: '{name}' is a group, expected a dataset")
    return datasets, problems


def check_datasets(path: Path, f: h5py.File) -> list[str]:
    """The problems of the two datasets every reader uses, ``delays`` (N, H, W) and
    ``labels`` (N,) of integers, of the file's other members (:func:`datasets_of`) and of
    every dataset's storage (:func:`storage_problem`)."""
    datasets, problems = datasets_of(path, f)
    delays, labels = datasets.get("delays"), datasets.get("labels")
    if delays is None or labels is None:
        return problems
    if delays.ndim != 3:
        problems.append(f"{path}: 'delays' has shape {delays.shape}, expected (N, H, W)")
    elif labels.shape != delays.shape[:1] or labels.dtype.kind not in "iu":
        problems.append(
            f"{path}: 'labels' is {labels.dtype} of shape {labels.shape}, expected integer "
            f"class indices of shape ({delays.shape[0]},)"
        )
    problems += [f"{path}: {p}" for p in map(storage_problem, datasets.values()) if p]
    return problems


def check_storage(path: Path, f: h5py.File) -> list[str]:
    """The problems of an open HDF5 file's members (:func:`datasets_of`) and of every
    dataset's storage (:func:`storage_problem`): what a reader of a file from elsewhere (a
    split, a sweep's frames file) checks before reading any data."""
    datasets, problems = datasets_of(path, f)
    return problems + [f"{path}: {p}" for p in map(storage_problem, datasets.values()) if p]


# deflate (gzip) compresses at most about 1032 : 1 (long runs of one byte); the files this
# package writes stay far below it (labels about 40 : 1, surface labels about 10 : 1)
MAX_COMPRESSION = 1032


# The largest chunk a reader inflates, uncompressed: reading any row of a chunk decompresses
# all of it, so one gzip chunk of 1,048,576 samples (1 GiB) in a 3.5 MB file made verify take
# 1.26 GB. The largest chunk this package writes: 256 samples x 64 beams x 1024 columns x 8
# bytes = 128 MiB (the scan-timed `emission_ns` of an HDL-64E at the widest width generate
# takes); its defaults stay far below (a VLP-16 split, 16 x 16: 256 KiB of delays; scan-timed
# HDL-64E, 64 x 16: 2 MiB; a KITTI crop of 50 x 118: 5.8 MiB; DVS 32 x 32: 1 MiB, its events in
# chunks of 65,536 rows: 512 KiB; a sweep frame of the HDL-64E, 64 x 2083: 0.5 MiB).
MAX_CHUNK_BYTES = 128 * 2**20
# The only filters the writers use (gzip and shuffle); any other (a plugin, scale-offset, ...)
# is refused before HDF5 looks for it
FILTERS = {h5py.h5z.FILTER_DEFLATE: "gzip", h5py.h5z.FILTER_SHUFFLE: "shuffle"}
_LAYOUTS = {h5py.h5d.COMPACT: "compact", h5py.h5d.VIRTUAL: "virtual"}


def storage_problem(dataset: h5py.Dataset) -> str | None:
    """Why a dataset is not stored as the writers of this package store theirs, or None: in
    the file's own bytes, contiguous or in chunks (not in external files, a virtual dataset
    mapped from other files, or compact), with no filter but gzip and shuffle, chunks of at
    most :data:`MAX_CHUNK_BYTES` uncompressed, and every declared byte backed
    (:func:`unbacked`). Checked from the dataset's creation properties alone, before any of
    its data is read."""
    name = dataset.name.lstrip("/")
    expected = "expected a dataset whose bytes are in the file, contiguous or chunked"
    try:
        plist = dataset.id.get_create_plist()
        layout = plist.get_layout()
        externals = plist.get_external_count()
        if dataset.is_virtual or layout == h5py.h5d.VIRTUAL:
            return f"'{name}' is an HDF5 virtual dataset (mapped from other files); {expected}"
        if externals:
            file = plist.get_external(0)[0].decode(errors="replace")
            return f"'{name}' is stored in the external file {file!r}; {expected}"
        if layout not in (h5py.h5d.CONTIGUOUS, h5py.h5d.CHUNKED):
            kind = _LAYOUTS.get(layout, f"layout {layout}")
            return f"'{name}' has {kind} storage; {expected}"
        if layout == h5py.h5d.CHUNKED:
            for index in range(plist.get_nfilters()):
                code, _, _, label = plist.get_filter(index)
                if code not in FILTERS:
                    label = label.decode(errors="replace") or "unknown"
                    return (
                        f"'{name}' asks for HDF5 filter {code} ({label}); expected only "
                        f"{' and '.join(FILTERS.values())}"
                    )
            chunk = math.prod(dataset.chunks) * dataset.dtype.itemsize
            if chunk > MAX_CHUNK_BYTES:
                return (
                    f"'{name}' is stored in chunks of {dataset.chunks} {dataset.dtype} "
                    f"({size_text(chunk)} each); expected chunks of at most "
                    f"{size_text(MAX_CHUNK_BYTES)}"
                )
    except (OSError, RuntimeError, ValueError, TypeError) as exc:
        return f"'{name}': storage unreadable ({first_line(exc)})"
    return unbacked(dataset)


def unbacked(dataset: h5py.Dataset) -> str | None:
    """Why a dataset's declared size is not backed by bytes in its file, or None.

    A small file can declare millions of samples (an HDF5 "bomb": a chunked dataset whose
    chunks were never written reads as fill values), and reading it would allocate all that
    was declared. The writers of this package (:class:`~simlidar.dataset.writer.SplitWriter`)
    write every chunk, gzip-compressed; so a dataset is refused unless every chunk is stored
    (a contiguous one: all its bytes) and the declared bytes are at most
    :data:`MAX_COMPRESSION` times the stored ones.
    """
    declared = dataset.size * dataset.dtype.itemsize
    if declared == 0:
        return None
    stored = dataset.id.get_storage_size()
    if dataset.chunks is not None:
        chunks = math.prod(-(-n // c) for n, c in zip(dataset.shape, dataset.chunks))
        written = dataset.id.get_num_chunks()
        held = f" in {written} of {chunks} chunks"
        complete = written >= chunks and declared <= stored * MAX_COMPRESSION
    else:
        held, complete = "", stored >= declared
    if complete:
        return None
    return (
        f"'{dataset.name.lstrip('/')}' declares {dataset.shape} {dataset.dtype} "
        f"({size_text(declared)}) but stores {size_text(stored)}{held}; expected a dataset "
        "whose bytes are in the file (every chunk written)"
    )


def read_split_info(path: Path) -> SplitInfo:
    """Open a split file and check it carries the simlidar schema: the required attributes
    and datasets, every attribute a reader parses (:func:`check_attributes`), ``delays`` and
    ``labels`` and the storage of every dataset (:func:`check_datasets`), and the version."""
    try:
        with h5py.File(path, "r") as f:
            attrs, problems = read_attrs(f)
            missing = [k for k in REQUIRED_ATTRS if k not in f.attrs]
            missing += [k for k in ("delays", "labels") if k not in f]
            if missing:
                named = ", ".join(f"'{k}'" for k in missing)
                raise DatasetError(f"{path}: not a simlidar split (missing {named})")
            problems += check_attributes(path, attrs) + check_datasets(path, f)
            if problems:
                more = f" (and {len(problems) - 1} more: simlidar verify)" * (len(problems) > 1)
                raise DatasetError(problems[0] + more)
            size, height, width = f["delays"].shape
            info = SplitInfo(path, size, width, attrs, height)
    except OSError as exc:
        raise DatasetError(f"{path}: cannot read as HDF5 ({first_line(exc)})") from None
    check_version(path, attrs["dataset_version"], info.source, written_version(attrs))
    return info


def written_version(attrs) -> str | None:
    """The version this simlidar writes for a split like this one, when it is not its
    source's current version: a split with a receiver is RAIN_WAVEFORM_VERSION (4.2.0) with
    rain or a stored waveform (``rain_rate_mm_h``, ``waveform_bin_ns`` in its configuration),
    RETURNS_VERSION (4.1.0) where its returns come from waveforms (attribute ``return_mode``),
    else SENSOR_VERSION (4.0.0); a scan-timed split is SCAN_VERSION (3.0.0); a generated split
    without a profile follows the physical rule, still written as PHYSICAL_VERSION (1.0.0)."""
    if split_source(attrs) != GENERATOR:
        return None
    if "receiver" in attrs:
        config = _decode(attrs.get("config", ""))
        if isinstance(config, dict) and {"rain_rate_mm_h", "waveform_bin_ns"} & config.keys():
            return RAIN_WAVEFORM_VERSION
        return RETURNS_VERSION if "return_mode" in attrs else SENSOR_VERSION
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


def entry_problem(entry: Path) -> str | None:
    """Why an entry of a dataset directory is not a file of its own, or None: a regular file
    itself (``lstat``), never a link (it would be read, hashed and packed as the file it points
    to, a private one say), a folder, a pipe, a socket or a device. What verify says of every
    entry and every reader of each split file."""
    try:
        mode = entry.lstat().st_mode
    except OSError as exc:
        return f"{entry}: cannot be read ({exc.strerror}); expected a regular file"
    if stat.S_ISREG(mode):
        return None
    target = f" to {os.readlink(entry)}" if stat.S_ISLNK(mode) else ""
    return (
        f"{entry}: is {file_kind(mode)}{target}, expected a regular file (a dataset "
        "directory holds only its own files, listed in SHA256SUMS)"
    )


def read_split(path: str | Path, split: str) -> SplitInfo:
    """The split ``split`` of the dataset directory ``path``, one file or sharded (every shard
    checked: the schema, its index and count, the same attributes and sample shape as the
    first); DatasetError naming the file otherwise."""
    path = Path(path)
    files = find_split_files(path, split)
    if not files:
        raise DatasetError(f"{path}: expected a dataset directory with {split}.h5")
    for file in files:  # never a link to another file (verify refuses it too)
        problem = entry_problem(file)
        if problem is not None:
            raise DatasetError(problem)
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
    """Read some datasets (all rows by default) of one split file; a ResourceError before
    reading when this process cannot hold them."""
    with h5py.File(path, "r") as f:
        datasets = [f[n] for n in names]
        count = len(range(*rows.indices(len(datasets[0])))) if isinstance(rows, slice) else None
        needed = [
            (len(rows) if count is None else count) * math.prod(d.shape[1:]) * d.dtype.itemsize
            for d in datasets
        ]
        if sum(needed):
            shapes = ", ".join(f"'{n}' {d.shape} {d.dtype}" for n, d in zip(names, datasets))
            check_memory(sum(needed), f"{path}: {shapes}")
        return {n: d[rows] for n, d in zip(names, datasets)}


def read_rows(files, sizes, names: tuple[str, ...], rows=slice(None)) -> dict[str, np.ndarray]:
    """Datasets ``names`` of a split written as ``files`` of ``sizes`` samples each: all rows,
    a slice, or sorted row indices into the whole split, concatenated in sample order."""
    if len(files) == 1:
        return load_arrays(files[0], names, rows)
    total = sum(sizes)
    wanted = np.arange(total)[rows] if isinstance(rows, slice) else np.asarray(rows)
    if not len(wanted):
        return load_arrays(files[0], names, slice(0, 0))
    with h5py.File(files[0], "r") as f:  # the parts, then their concatenation
        row = sum(math.prod(f[n].shape[1:]) * f[n].dtype.itemsize for n in names)
    check_memory(2 * len(wanted) * row, f"{files[0].parent}: {len(wanted)} rows of {names}")
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
