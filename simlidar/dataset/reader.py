"""Reading split files: the schema and version checks every reader goes through."""

import json
import math
import warnings
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from simlidar.dataset.schema import (
    ATTRIBUTES,
    REQUIRED_ATTRS,
    SOURCE_ATTRS,
    SPLITS,
    expected_shapes,
    in_motion,
    reported_returns,
    split_source,
)
from simlidar.dataset.shards import find_split_files, shard_of
from simlidar.dataset.storage import datasets_of, entry_problem
from simlidar.dataset.stream import NAME as STREAM_SOURCE
from simlidar.dataset.version import (
    CALIBRATED_VERSION,
    GENERATOR,
    MOTION_VERSION,
    PHYSICAL_VERSION,
    SCAN_VERSION,
    SOURCES,
    major,
)
from simlidar.errors import ConfigError, DatasetError, first_line, shown
from simlidar.resources import check_memory


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
    if not {"catalog", "layout_names", "object_names"} & bad and split_source(attrs) == GENERATOR:
        problems += _catalog_problems(path, attrs)
    if "receiver" in attrs and split_source(attrs) in (GENERATOR, STREAM_SOURCE):
        problems += _receiver_problems(path, attrs, bad)
    waveform = [name for name in ("waveform_bin_ns", "waveform_bins") if name in attrs]
    if waveform and (len(waveform) == 1 or "return_mode" not in attrs):
        problems.append(
            f"{path}: attribute(s) {waveform}: expected 'waveform_bin_ns' and 'waveform_bins' "
            "together, in a split whose returns come from waveforms ('return_mode')"
        )
    return problems


def _catalog_problems(path: Path, attrs: dict) -> list[str]:
    """A generated split's ``catalog`` describes each of its layouts and objects (after the
    first, ``none``), as its card quotes them: ``catalog[kind][name]["description"]``, a
    string."""
    catalog = attrs.get("catalog")
    if catalog is None:
        return []  # named as missing
    for kind, names in (
        ("layouts", attrs.get("layout_names", [])),
        ("objects", attrs.get("object_names", [])[1:]),
    ):
        recipes = catalog.get(kind)
        for name in names:
            recipe = recipes.get(name) if isinstance(recipes, dict) else None
            if not (isinstance(recipe, dict) and isinstance(recipe.get("description"), str)):
                return [
                    f"{path}: attribute 'catalog' has {kind}.{shown(name)} = {shown(recipe)}; "
                    f"expected the recipe of each of the split's {kind}, with a description"
                ]
    return []


def _receiver_problems(path: Path, attrs: dict, bad: set) -> list[str]:
    """A generated or stream split with a receiver: its receiver and materials attributes
    present and each what its file would hold (the card and readers use their values)."""
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


@dataclass
class SplitCheck:
    """What :func:`check_split` found in an open split file."""

    attrs: dict  # the attributes, decoded
    datasets: dict[str, h5py.Dataset]  # the root's datasets whose storage is sound, by name
    shapes: dict[str, tuple] | None  # name -> (dtype, shape) the schema asks for; None: unknown
    size: int | None  # samples N (None where no labels say)
    height: int | None  # rows H of a sample (None where 'delays' is not (N, H, W))
    width: int | None  # columns W
    problems: list[str]


def check_split(path: Path, f: h5py.File) -> SplitCheck:
    """Everything a split file's structure must satisfy before any reader uses it, read from
    its attributes and metadata alone (no data): the required attributes, each attribute's
    rule (:func:`check_attributes`), every object of the file (:func:`datasets_of`), each
    dataset the schema of its source, timing, receiver, returns and waveform asks for, of that
    dtype and shape, and attributes that agree with the data (:func:`_contradictions`). The
    one check of a split's structure: the readers, the loaders and ``verify`` all go through
    it."""
    attrs, problems = read_attrs(f)
    problems += [f"{path}: attribute '{k}' missing" for k in REQUIRED_ATTRS if k not in f.attrs]
    attribute_problems = check_attributes(path, attrs)
    problems += attribute_problems
    datasets, more = datasets_of(path, f)
    problems += more
    labels, delays = datasets.get("labels"), datasets.get("delays")
    size = labels.shape[0] if labels is not None and labels.ndim else None
    height, width = delays.shape[1:] if delays is not None and delays.ndim == 3 else (None, None)
    if delays is not None and width is None:
        problems.append(f"{path}: 'delays' has shape {delays.shape}, expected (N, H, W)")
    found = SplitCheck(attrs, datasets, None, size, height, width, problems)
    source, version = split_source(attrs), attrs.get("dataset_version")
    if not (
        ATTRIBUTES["source"].accepts(source) and ATTRIBUTES["dataset_version"].accepts(version)
    ):
        return found  # named by check_attributes
    events = datasets["event_t_us"].shape[0] if "event_t_us" in datasets else 0
    bins = attrs.get("waveform_bins", 0)
    bins = bins if ATTRIBUTES["waveform_bins"].accepts(bins) else 0  # named above
    rotations = attrs.get("rotations", 0)
    try:
        found.shapes = expected_shapes(
            source,
            size,
            height,
            width,
            events,
            attrs.get("timing", "flash"),
            "receiver" in attrs,
            reported_returns(attrs),
            bins,
            in_motion(attrs),
            rotations if ATTRIBUTES["rotations"].accepts(rotations) else 0,  # named above
        )
    except DatasetError as exc:  # an unknown source
        problems.append(f"{path}: {exc}")
        return found
    for name, (dtype, shape) in found.shapes.items():
        if name not in datasets:
            if name not in f:  # else named by datasets_of
                problems.append(f"{path}: dataset '{name}' missing")
            continue
        ds = datasets[name]
        if ds.dtype != np.dtype(dtype):
            problems.append(f"{path}: '{name}' is {ds.dtype}, expected {dtype}")
        if size is not None and width is not None and ds.shape != shape:
            problems.append(f"{path}: '{name}' has shape {ds.shape}, expected {shape}")
    if not attribute_problems and width is not None:
        problems += _contradictions(path, attrs, height, width)
    return found


def _contradictions(path: Path, attrs: dict, height: int, width: int) -> list[str]:
    """Attributes (each sound by its own rule) that contradict a split's H x W samples: the
    rows' laser ids and elevations and the columns' azimuths are one a row or column, and a
    generated split's sensor has one beam a row, each laser id one of its beams."""
    problems = []
    for name, count, what in (
        ("row_laser_ids", height, "rows"),
        ("row_elevation_deg", height, "rows"),
        ("column_azimuth_deg", width, "columns"),
    ):
        if name in attrs and len(attrs[name]) != count:
            problems.append(
                f"{path}: attribute '{name}' holds {len(attrs[name])} values for the samples' "
                f"{count} {what}; expected one a {what[:-1]}"
            )
    if split_source(attrs) == GENERATOR and "sensor" in attrs:
        beams = len(attrs["sensor"].get("elevations_deg", ()))
        if beams != height:
            problems.append(
                f"{path}: attribute 'sensor' has {beams} beams, but the samples have {height} "
                "rows; expected one row a beam"
            )
        lasers = attrs.get("row_laser_ids", [])
        if len(set(lasers)) != len(lasers) or any(laser >= beams for laser in lasers):
            problems.append(
                f"{path}: attribute 'row_laser_ids' is {shown(lasers)}; expected distinct "
                f"laser ids of the sensor's {beams} beams"
            )
    return problems


# The datasets whose values every reader checks as it reads them: the network's inputs and
# the labels (what a model is trained and scored on)
CHECKED_VALUES = ("delays", "clean_delays", "labels")


def value_problems(path, attrs: dict, arrays: dict[str, np.ndarray]) -> list[str]:
    """The problems of values read from a split (rows of :data:`CHECKED_VALUES`; others are
    not looked at), each starting with ``path`` (a file, or where in it): delays outside
    [0, 1] or NaN, labels outside the split's classes."""
    problems = []
    for name, values in arrays.items():
        if name == "labels":
            classes = len(attrs["class_names"])
            if values.size and not (0 <= values.min() and values.max() < classes):
                problems.append(f"{path}: labels outside 0..{classes - 1}")
        elif name in CHECKED_VALUES and not ((values >= 0) & (values <= 1)).all():  # NaN too
            problems.append(f"{path}: '{name}' has values outside [0, 1] or NaN")
    return problems


def read_split_info(path: Path) -> SplitInfo:
    """Open a split file and check it carries the simlidar schema (:func:`check_split`) and a
    version this simlidar reads (:func:`check_version`)."""
    try:
        with h5py.File(path, "r") as f:
            missing = [k for k in REQUIRED_ATTRS if k not in f.attrs]
            missing += [k for k in ("delays", "labels") if k not in f]
            if missing:
                named = ", ".join(f"'{k}'" for k in missing)
                raise DatasetError(f"{path}: not a simlidar split (missing {named})")
            found = check_split(path, f)
            problems = found.problems
            if problems:
                more = f" (and {len(problems) - 1} more: simlidar verify)" * (len(problems) > 1)
                raise DatasetError(problems[0] + more)
            info = SplitInfo(path, found.size, found.width, found.attrs, found.height)
    except OSError as exc:
        raise DatasetError(f"{path}: cannot read as HDF5 ({first_line(exc)})") from None
    check_version(path, info.attrs["dataset_version"], info.source, written_version(info.attrs))
    return info


def written_version(attrs) -> str | None:
    """The version this simlidar writes for a split like this one, when it is not its
    source's current version: a split with a receiver is CALIBRATED_VERSION (5.0.0; a 4.x one
    reads, with a warning that its records changed); one in motion is MOTION_VERSION (4.3.0);
    a scan-timed split is SCAN_VERSION (3.0.0); a generated split
    without a profile follows the physical rule, still written as PHYSICAL_VERSION (1.0.0)."""
    if split_source(attrs) != GENERATOR:
        return None
    config = _decode(attrs.get("config", ""))
    if "receiver" in attrs:
        return CALIBRATED_VERSION
    if in_motion({"config": config}):
        return MOTION_VERSION
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
