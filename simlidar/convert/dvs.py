"""DVS barrel recordings (Orchard et al. 2015) -> first-spike times in the simlidar schema.

Input: the published MATLAB file layout, a struct array ``ROI`` (or a cell array of 1 x 1
structs), one entry per recording, holding the event stream of one character cropped to
32 x 32 pixels: x and y addresses (1-based by default, as MATLAB writes them), polarity and
timestamps in microseconds. A sample's ``delays[y, x]`` is the time of the pixel's first event
(either polarity) after the recording's first event, over a time window; 1.0 = no spike.
``docs/converters.md`` has the details; :func:`convert_dvs_barrel` is the entry point.
"""

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from simlidar.atomic import building
from simlidar.convert.common import (
    choose_test,
    delays_from_times,
)
from simlidar.convert.common import stream as random_stream
from simlidar.convert.config import DvsConfig
from simlidar.dataset.dvs_barrel import CLASSES
from simlidar.dataset.schema import CONVERTED_SCHEMAS, SPLITS, expected_shapes
from simlidar.dataset.version import SOURCES
from simlidar.dataset.writer import SplitWriter
from simlidar.errors import ConfigError, DatasetError
from simlidar.generator.declared_card import converted_split_attrs, write_release_files
from simlidar.release.checksums import sha256_file

SOURCE = "dvs-barrel"
PIXELS = 32  # rows and columns of a recording
# field -> accepted names (any case); a struct with exactly these four fields under other names
# is read by position, x, y, polarity, timestamp, as public loaders of the published file do
_FIELDS = {
    "x": ("x",),
    "y": ("y",),
    "p": ("p", "pol", "polarity"),
    "ts": ("ts", "t", "timestamp", "timestamps"),
}


@dataclass(frozen=True)
class Recording:
    """One recording's events, addresses 0-based: x, y, p, t_us (e,) each."""

    x: np.ndarray  # int64 column
    y: np.ndarray  # int64 row
    p: np.ndarray  # int8 polarity as recorded (-1/1 or 0/1)
    t_us: np.ndarray  # int64 timestamp as recorded, microseconds
    label: str | None  # from the struct's 'label' field, if any


def _entries(path: Path) -> list:
    """The ROI entries (numpy records with named fields), in MATLAB's index order."""
    from scipy.io import loadmat
    from scipy.io.matlab import MatReadError

    if not path.is_file():
        raise DatasetError(f"{path}: no such file (expected the MATLAB file of recordings)")
    try:
        mat = loadmat(path)
    except NotImplementedError:
        raise DatasetError(
            f"{path}: a MATLAB v7.3 (HDF5) file; expected one saved with -v7"
        ) from None
    except (MatReadError, ValueError, TypeError, OSError) as exc:
        raise DatasetError(f"{path}: cannot read as a MATLAB file ({exc})") from None
    if "ROI" not in mat:
        found = ", ".join(k for k in mat if not k.startswith("__")) or "nothing"
        raise DatasetError(
            f"{path}: no variable 'ROI' (found {found}); expected the struct array of recordings"
        )
    roi = mat["ROI"].flatten(order="F")
    if roi.dtype.names:
        return list(roi)
    entries = []
    for k, cell in enumerate(roi, 1):
        if not (isinstance(cell, np.ndarray) and cell.dtype.names and cell.size == 1):
            raise DatasetError(f"{path}: ROI({k}) is not a struct; expected a struct array")
        entries.append(cell.flat[0])
    return entries


def _field_names(path: Path, k: int, names: tuple[str, ...]) -> dict[str, str]:
    lower = {n.lower(): n for n in names}
    found = {
        f: next((lower[a] for a in aliases if a in lower), None) for f, aliases in _FIELDS.items()
    }
    if None not in found.values():
        return found
    events = [n for n in names if n.lower() != "label"]
    if len(events) == 4:
        return dict(zip(_FIELDS, events))
    raise DatasetError(
        f"{path}: ROI({k}) has fields {', '.join(names)}; expected x, y, p (or "
        "pol, polarity), ts (or t, timestamp)"
    )


def _integers(path: Path, where: str, values: np.ndarray, low: float, high: float) -> np.ndarray:
    values = np.asarray(values).ravel()
    if values.dtype.kind not in "iuf" or not np.isfinite(values).all():
        raise DatasetError(f"{path}: {where} holds {values.dtype} values; expected integers")
    bad = (values != np.round(values)) | (values < low) | (values > high)
    if bad.any():
        raise DatasetError(
            f"{path}: {where} has {values[bad][0]:g}; expected integers in [{low:g}, {high:g}]"
        )
    return values.astype(np.int64)


def read_recordings(path: str | Path, address_base: int = 1) -> list[Recording]:
    """Every recording of a DVS barrel MATLAB file, checked (DatasetError naming ROI(k))."""
    path = Path(path)
    recordings = []
    for k, entry in enumerate(_entries(path), 1):
        names = _field_names(path, k, entry.dtype.names)
        low, high = address_base, address_base + PIXELS - 1
        x = _integers(path, f"ROI({k}).{names['x']}", entry[names["x"]], low, high) - low
        y = _integers(path, f"ROI({k}).{names['y']}", entry[names["y"]], low, high) - low
        p = _integers(path, f"ROI({k}).{names['p']}", entry[names["p"]], -1, 1).astype(np.int8)
        t = _integers(path, f"ROI({k}).{names['ts']}", entry[names["ts"]], -(2**62), 2**62)
        if not len(x) == len(y) == len(p) == len(t):
            counts = f"{len(x)} x, {len(y)} y, {len(p)} polarity and {len(t)} time values"
            raise DatasetError(f"{path}: ROI({k}) has {counts}; expected one per event")
        label = None
        if "label" in {n.lower() for n in entry.dtype.names}:
            name = next(n for n in entry.dtype.names if n.lower() == "label")
            value = np.asarray(entry[name]).ravel()
            label = str(value[0]).strip().upper() if value.dtype.kind == "U" and value.size else ""
            if label not in CLASSES:
                raise DatasetError(
                    f"{path}: ROI({k}).{name} is {value!r}; expected one character 0-9 or A-Z"
                )
        recordings.append(Recording(x, y, p, t, label))
    if not recordings:
        raise DatasetError(f"{path}: ROI holds no recordings")
    return recordings


def first_spikes(recording: Recording, window_us: float) -> np.ndarray:
    """(32, 32) float32 delays: each pixel's first event after the recording's first, over
    ``window_us``; 1.0 where a pixel is silent within the window."""
    first = np.full(PIXELS * PIXELS, np.inf)
    if len(recording.t_us):
        since = (recording.t_us - recording.t_us.min()).astype(np.float64)
        np.minimum.at(first, recording.y * PIXELS + recording.x, since)
    first[np.isinf(first)] = np.nan
    return delays_from_times(first.reshape(PIXELS, PIXELS), window_us)


def default_window_us(recordings: list[Recording]) -> float:
    """The longest recording's span plus 1 us, so that every event lies inside the window."""
    spans = [int(r.t_us.max() - r.t_us.min()) for r in recordings if len(r.t_us)]
    return float(max(spans, default=0) + 1)


def split_recordings(labels: np.ndarray, config: DvsConfig) -> dict[str, np.ndarray]:
    """Recording indices of each split: per class, a seeded choice of test_fraction of its
    recordings (at least one in each split when the class has two or more; a single one goes
    to train). DatasetError when no class has two recordings (no test split possible)."""
    test = np.zeros(len(labels), dtype=bool)
    for c in range(len(CLASSES)):
        members = np.nonzero(labels == c)[0]
        if len(members) >= 2:
            chosen = choose_test(len(members), config.test_fraction, random_stream(config.seed, c))
            test[members[chosen]] = True
    if not test.any():
        raise DatasetError(
            f"{len(labels)} recording(s), no class with two: expected at least "
            "two recordings of a class, so that train and test differ"
        )
    return {"train": np.nonzero(~test)[0], "test": np.nonzero(test)[0]}


def write_split(
    path: Path,
    recordings: list[Recording],
    rows: np.ndarray,
    delays: np.ndarray,
    labels: np.ndarray,
    attrs: dict,
) -> None:
    """One split file: the samples' records (N rows) and their events, concatenated (E rows).

    path : the split file to write (``train.h5``, ``test.h5``)
    recordings : the split's N recordings, in the order of ``rows``
    rows : (N,) the recordings' indices in ROI; delays : (N, 32, 32); labels : (N,)
    attrs : the split's attributes
        (:func:`~simlidar.generator.declared_card.converted_split_attrs`, and ``time_window_us``)
    """
    schema = CONVERTED_SCHEMAS[SOURCE]
    full = expected_shapes(SOURCE, len(rows), PIXELS, PIXELS)
    per_sample = {n: (d, shape[1:]) for n, (d, shape) in full.items() if schema[n][1][0] == "N"}
    count = np.array([len(r.t_us) for r in recordings], dtype=np.int64)
    writer = SplitWriter(path, len(rows), per_sample, attrs, frozenset({"delays"}))
    try:
        writer.append(
            {
                "delays": delays,
                "labels": labels,
                "recording": rows.astype(np.int64),
                "event_start": np.cumsum(count) - count,
                "event_count": count,
            }
        )
        for name, field in (
            ("event_x", "x"),
            ("event_y", "y"),
            ("event_p", "p"),
            ("event_t_us", "t_us"),
        ):
            values = np.concatenate([getattr(r, field) for r in recordings])
            writer.add_rows(name, values, schema[name][0])
        writer.close()
    finally:
        writer.abort()  # a no-op after close()


def dvs_name() -> str:
    """``dvs-barrel-32x32-v<version>``."""
    return f"dvs-barrel-{PIXELS}x{PIXELS}-v{SOURCES[SOURCE][0]}"


# the signature of every converter (convert_kitti's): source, out, the shared flags, options
def convert_dvs_barrel(
    mat_file: str | Path,
    out: str | Path,
    *,
    force: bool = False,
    progress: bool = True,
    preview: bool = True,
    **options,
) -> Path:
    """Convert a DVS barrel MATLAB file (a struct array ROI of recordings: x, y, polarity,
    timestamps in us; 36 characters, 32 x 32 pixels) into first-spike times, written to
    OUT/dvs-barrel-32x32-v<version>/ with the raw events kept alongside.

    Each recording is one sample: a pixel's first event after the recording's first, over
    window_us (default: the longest recording + 1 us), 1.0 = no spike. Classes come from labels
    (one character per recording) or the struct's 'label' field. Per class, test_fraction of the
    recordings go to test (seeded; at least one stays in train). Returns the dataset directory.

    mat_file : the MATLAB file (read with scipy.io.loadmat; a file from elsewhere: checked)
    out : the folder that receives the dataset directory (made if missing)
    force : replace a dataset directory of the same name (else an error names it)
    progress : a progress bar on stderr
    preview : draw the dataset's ``preview.png``
    options : the fields of :class:`~simlidar.convert.config.DvsConfig` (labels, window_us,
        address_base, test_fraction, seed), each with its default there
    """
    from tqdm import tqdm

    config = DvsConfig(**options)
    recordings = read_recordings(mat_file, config.address_base)
    classes = config.labels or tuple(r.label for r in recordings)
    if len(classes) != len(recordings) or None in classes:
        raise ConfigError(
            f"{mat_file}: {len(recordings)} recordings, "
            + (f"{len(classes)} labels given" if config.labels else "no 'label' field in ROI")
            + "; expected one character 0-9 or A-Z per recording (labels=...)"
        )
    y = np.array([CLASSES.index(c) for c in classes], dtype=np.int64)
    window = config.window_us or default_window_us(recordings)
    delays = np.stack(
        [
            first_spikes(r, window)
            for r in tqdm(recordings, unit="recording", disable=not progress, desc="dvs-barrel")
        ]
    )
    splits = split_recordings(y, config)
    sensor = {
        "name": "DVS128 (Orchard et al. 2015), 32 x 32 stabilised character crops",
        "rows": PIXELS,
        "columns": PIXELS,
        "time_unit": "us",
    }
    name = dvs_name()
    with building(out, name, force) as temp:
        for split in SPLITS:
            rows = splits[split]
            attrs = converted_split_attrs(
                SOURCE, split, config, CLASSES, "character", sensor, sha256_file(mat_file)
            )
            attrs["time_window_us"] = float(window)
            write_split(
                temp / f"{split}.h5",
                [recordings[i] for i in rows],
                rows,
                delays[rows],
                y[rows],
                attrs,
            )
        write_release_files(temp, name, preview)
    return Path(out) / name
