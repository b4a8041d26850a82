"""Sharded splits: a split of more samples than a limit is written as several files.

The names follow the Hugging Face convention, ``train-00000-of-00016.h5`` ... ``train-00015-of-
00016.h5``: shard ``i`` of ``n`` holds the samples ``i * S`` .. ``(i + 1) * S - 1`` of the split
(``S`` the shard size; the last shard holds the rest), each a complete split file in the same
schema with two more attributes, ``shard`` (i) and ``shards`` (n). A split of at most ``S``
samples is one file, ``train.h5``, as before (docs/dataset-format.md, "Sharded splits").
"""

import re
from itertools import islice
from pathlib import Path

from simlidar.dataset.schema import SPLITS
from simlidar.errors import DatasetError

SHARD_SAMPLES = 250_000  # samples a shard file holds by default (about 330 MB at 16 x 16)
# at least five digits, as Hugging Face writes them; at most 18, so that a number always fits
_SHARD = re.compile(r"^(?P<split>[a-z]+)-(?P<index>\d{5,18})-of-(?P<count>\d{5,18})\.h5$")


def shard_name(split: str, index: int, count: int) -> str:
    """``<split>-<index>-of-<count>.h5``, numbers of at least five digits."""
    return f"{split}-{index:05d}-of-{count:05d}.h5"


def shard_bounds(size: int, shard_samples: int) -> list[tuple[int, int]]:
    """The (start, stop) of each file of a split of ``size`` samples: one file when ``size`` is
    at most ``shard_samples``."""
    if shard_samples < 1:
        raise DatasetError(f"shard size {shard_samples}: expected a number of samples >= 1")
    if size <= shard_samples:
        return [(0, size)]
    return [(s, min(s + shard_samples, size)) for s in range(0, size, shard_samples)]


def split_file_names(split: str, size: int, shard_samples: int) -> list[str]:
    """The file names a split of ``size`` samples is written as."""
    bounds = shard_bounds(size, shard_samples)
    if len(bounds) == 1:
        return [f"{split}.h5"]
    return [shard_name(split, i, len(bounds)) for i in range(len(bounds))]


def shard_of(name: str) -> tuple[str, int, int] | None:
    """(split, index, count) of a shard file name; None for any other name."""
    match = _SHARD.match(name)
    if match is None:
        return None
    return match["split"], int(match["index"]), int(match["count"])


def split_of(name: str) -> str | None:
    """The split a file name belongs to (``train.h5``, ``train-00003-of-00016.h5``: train)."""
    shard = shard_of(name)
    if shard is not None:
        return shard[0]
    stem, dot, ext = name.rpartition(".")
    return stem if dot and ext == "h5" and stem in SPLITS else None


def find_split_files(path: str | Path, split: str) -> list[Path]:
    """The files of ``split`` in the dataset directory ``path``, in sample order: ``split.h5``,
    or every shard. An empty list when there are none; DatasetError when the shards are
    incomplete (a missing index, counts that disagree) or sit beside ``split.h5``."""
    path = Path(path)
    single = path / f"{split}.h5"
    shards = []
    for file in path.iterdir() if path.is_dir() else ():
        shard = shard_of(file.name)
        if shard is not None and shard[0] == split and file.is_file():
            shards.append((shard[1], shard[2], file))
    if not shards:
        return [single] if single.is_file() else []
    if single.is_file():
        raise DatasetError(
            f"{path}: both {single.name} and {len(shards)} {split} shard files; expected one or "
            "the other"
        )
    counts = sorted({count for _, count, _ in shards})
    if len(counts) > 1:
        raise DatasetError(
            f"{path}: {split} shards of different counts ({', '.join(map(str, counts))}); "
            "expected one set of shards"
        )
    count = counts[0]
    present = {index for index, _, _ in shards}
    # the count comes from a file name (train-00000-of-9999999999.h5): look only as far as
    # the files on disk reach, never build a list of every index it claims
    missing = [shard_name(split, i, count) for i in islice(_absent(present, count), 4)]
    beyond = [shard_name(split, i, count) for i in sorted(present) if i >= count]
    if missing or beyond:
        shown = ", ".join((missing or beyond)[:3]) + (", ..." if len(missing or beyond) > 3 else "")
        what = f"missing {shown}" if missing else f"{shown} beyond the count"
        raise DatasetError(
            f"{path}: {split} shards incomplete ({what}); expected shards 0..{count - 1}"
        )
    return [file for _, _, file in sorted(shards)]


def _absent(present: set[int], count: int):
    """The indices 0 .. count - 1 not in ``present``, lazily (at most len(present) + k steps
    for the first k)."""
    return (i for i in range(count) if i not in present)
