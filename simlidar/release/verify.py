"""``simlidar verify``: is a dataset directory complete, intact and in the schema?"""

from pathlib import Path

import h5py

from simlidar.dataset.reader import (
    CHECKED_VALUES,
    check_split,
    check_version,
    value_problems,
    written_version,
)
from simlidar.dataset.schema import SPLITS, split_source
from simlidar.dataset.shards import find_split_files, shard_of, split_of
from simlidar.dataset.stream import NAME as STREAM
from simlidar.dataset.stream_checks import event_limits, event_problems, event_value_problems
from simlidar.errors import DatasetError, first_line
from simlidar.release.card import read_front_matter
from simlidar.release.checksums import check_sums

_BLOCK_BYTES = 64 * 2**20  # bytes of a dataset read at a time: memory stays flat


def _check_split(
    path: Path, split: str, shard: tuple[int, int] | None = None
) -> tuple[list[str], int | None]:
    """The problems of one split file (of ``split``; ``shard``: its index and count when the
    split is sharded) and its number of samples (None where unreadable)."""
    try:
        f = h5py.File(path, "r")
    except OSError as exc:
        return [f"{path}: cannot read as HDF5 ({first_line(exc)})"], None
    with f:
        found = check_split(path, f)
        attrs, problems, size = found.attrs, found.problems, found.size
        datasets, shapes = found.datasets, found.shapes
        if shapes is None:  # an unknown source or version: named by check_split
            return problems, None
        try:
            check_version(
                path, attrs["dataset_version"], split_source(attrs), written_version(attrs)
            )
        except DatasetError as exc:
            problems.append(str(exc))
        if problems or size is None or found.width is None:  # not readable as the schema says
            return problems, None
        if attrs["split"] != split:
            problems.append(
                f"{path}: holds the {attrs['split']!r} split, expected {split!r} (files swapped "
                "or renamed?)"
            )
        own = (attrs.get("shard"), attrs.get("shards"))
        if own != (shard or (None, None)):
            expected = f"shard={shard[0]}, shards={shard[1]}" if shard else "none"
            problems.append(
                f"{path}: shard attributes shard={own[0]!r}, shards={own[1]!r}; expected "
                f"{expected} (shard files renamed?)"
            )
        row_bytes = max(ds.nbytes // max(size, 1) for ds in datasets.values())
        block = max(1, _BLOCK_BYTES // max(row_bytes, 1))
        try:
            for start in range(0, size, block):
                rows = slice(start, start + block)
                names = [n for n in CHECKED_VALUES if n in shapes]
                problems += value_problems(path, attrs, {n: datasets[n][rows] for n in names})
            if "event_count" in shapes:
                offsets = f["event_start"][:], f["event_count"][:]
                tiled = event_problems(path, *offsets, f["event_t_us"].shape[0])
                problems += tiled
                if not tiled and split_source(attrs) == STREAM:  # its events' values too
                    limits = event_limits(attrs, found.height, found.width)
                    problems += event_value_problems(path, f, limits)
        except OSError as exc:  # a chunk that does not decompress
            problems.append(f"{path}: unreadable data ({first_line(exc)})")
    return sorted(set(problems), key=problems.index), size


def check_trainable(path: str | Path) -> None:
    """Refuse a dataset that :func:`verify` rejects, before any training: a DatasetError with
    the first problem (``train`` and ``bench`` call it once per dataset)."""
    problems = verify(path)
    if problems:
        more = f" (and {len(problems) - 1} more: simlidar verify {path})" * (len(problems) > 1)
        raise DatasetError(f"{problems[0]}{more}; expected a dataset that simlidar verify accepts")


def verify(path: str | Path) -> list[str]:
    """Every problem found in a dataset directory; an empty list means it is sound.

    Checks the checksums, the card's front matter, the HDF5 schema (datasets, dtypes, shapes,
    attributes), value ranges (delays in [0, 1], labels within the class list) and that each
    split holds as many samples as the card says. Raises DatasetError if ``path`` is not a
    dataset directory at all.
    """
    path = Path(path)
    if not path.is_dir():
        raise DatasetError(f"{path}: expected a dataset directory")
    if not any(split_of(p.name) for p in path.iterdir()):
        raise DatasetError(f"{path}: not a simlidar dataset (no train.h5 or test.h5)")
    # the splits' problems first (they say what is wrong with the data), then the card's,
    # then the checksums' (which only say that something changed)
    problems, card = [], []
    sizes: dict[str, int] = {}
    try:
        meta = read_front_matter(path)
        sizes = {s["name"]: s["num_examples"] for s in meta["dataset_info"]["splits"]}
    except (DatasetError, KeyError, TypeError) as exc:
        card.append(
            str(exc)
            if isinstance(exc, DatasetError)
            else f"{path / 'README.md'}: dataset_info.splits malformed"
        )
    for split in SPLITS:
        try:
            files = find_split_files(path, split)
        except DatasetError as exc:  # incomplete shards
            problems.append(str(exc))
            continue
        if not files:
            problems.append(f"{path / f'{split}.h5'}: missing")
            continue
        sharded = shard_of(files[0].name) is not None
        found, total = [], 0
        for index, file in enumerate(files):
            more, size = _check_split(file, split, (index, len(files)) if sharded else None)
            found += more
            total = None if size is None or total is None else total + size
        problems += found
        expected = sizes.get(split)
        if expected is not None and total is not None and total != expected:
            where = f"{path / f'{split}-*.h5'} ({len(files)} shards)" if sharded else files[0]
            problems.append(f"{where}: {total} samples, the card says {expected}")
    return problems + card + check_sums(path)
