"""Writing split files: a streaming HDF5 writer whose bytes do not depend on how rows arrive.

Files are written deterministically: no timestamps, fixed chunking, gzip (level 1), shuffle
where it pays. Level 1 because the noisy delays barely compress and higher levels cost time
for ~1 %.
"""

import os
import zlib
from contextlib import contextmanager
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import h5py
import numpy as np

from simlidar.dataset.schema import CHUNK_SAMPLES
from simlidar.errors import DatasetError, first_line


def attrs_fit(attrs: dict) -> bool:
    """Whether every attribute fits an object header message of the earliest HDF5 format
    (64 KB each, less its name, type and shape), as tried in a file held in memory: e.g. at
    most 8,182 int64 values under the name ``frames_without_objects``."""
    with h5py.File(
        "attrs_fit", "w", driver="core", backing_store=False, libver=("earliest", "v110")
    ) as probe:
        for key, value in attrs.items():
            try:
                probe.attrs[key] = value
            except OSError:  # "object header message is too large"
                return False
    return True


GZIP_LEVEL = 1


def deflated(chunk: np.ndarray, shuffle: bool) -> bytes:
    """One whole chunk as HDF5's filters store it: its bytes shuffled (every value's first
    byte, then every second byte, ...: the shuffle filter) where ``shuffle``, then compressed
    by zlib at :data:`GZIP_LEVEL` (the deflate filter calls zlib's ``compress2``)."""
    raw = np.ascontiguousarray(chunk).view(np.uint8).reshape(chunk.size, chunk.itemsize)
    return zlib.compress((raw.T if shuffle else raw).tobytes(), GZIP_LEVEL)


@cache
def deflate_matches_hdf5() -> bool:
    """Whether :func:`deflated` gives the bytes HDF5's own filters store, tried once a process
    on a probe written through them in a file held in memory (both use zlib, but not
    necessarily the same build: h5py's wheel may carry its own). Where they differ, the
    writer leaves the filters to HDF5, so a file's bytes never depend on which one ran."""
    probe = np.random.default_rng(0).random((64, 16, 16), dtype=np.float32)
    probe[probe > 0.7] = 1.0  # runs of one value, as the "no return" delays make
    with h5py.File("deflate_probe", "w", driver="core", backing_store=False) as file:
        for shuffle in (False, True):
            data = file.create_dataset(
                f"probe{shuffle}",
                data=probe,
                chunks=probe.shape,
                compression="gzip",
                compression_opts=GZIP_LEVEL,
                shuffle=shuffle,
            )
            if data.id.read_direct_chunk((0, 0, 0)) != (0, deflated(probe, shuffle)):
                return False
    return True


def whole_chunks(rows: np.ndarray, step: int):
    """``rows`` cut into chunks of ``step`` rows, the last padded with zeros (HDF5's fill
    value, as HDF5 stores a dataset's last chunk)."""
    for first in range(0, len(rows), step):
        chunk = rows[first : first + step]
        if len(chunk) < step:
            pad = np.zeros((step - len(chunk), *chunk.shape[1:]), chunk.dtype)
            chunk = np.concatenate([chunk, pad])
        yield chunk


def chunk_steps(
    size: int, names, chunk: int = CHUNK_SAMPLES, chunk_rows: dict[str, int] | None = None
) -> tuple[int, dict[str, int]]:
    """The rows a :class:`SplitWriter` of ``size`` rows writes at a time (every dataset in
    turn), and each dataset's rows a chunk (``chunk_rows`` where given, never more)."""
    group = min(chunk, size)
    return group, {name: min(group, (chunk_rows or {}).get(name, group)) for name in names}


@dataclass(frozen=True)
class Deflated:
    """One dataset's rows of a block already cut into whole chunks of its file and compressed
    (:func:`deflated_block`): what a worker process hands the writer in place of the rows."""

    rows: int
    chunks: tuple[bytes, ...]


def deflated_block(
    block: dict[str, np.ndarray],
    offset: int,
    size: int,
    shapes: dict[str, tuple[str, tuple]],
    shuffled: frozenset[str] = frozenset(),
    chunk: int = CHUNK_SAMPLES,
    chunk_rows: dict[str, int] | None = None,
) -> dict[str, Deflated] | None:
    """``block`` (rows ``offset`` .. of a file of ``size`` rows, the datasets of ``shapes``)
    compressed as its :class:`SplitWriter` would compress it, for the writer to store as it is
    (:meth:`SplitWriter.append`); so the compression runs where the rows are made. None where
    the writer must cut the rows itself: the block does not start at a whole chunk of every
    dataset and end at one or at the file's end, or :func:`deflated` does not give HDF5's
    bytes here.

    block : one array per dataset, equally long
    offset : the file row of the block's first row
    size : the file's rows
    shapes : name -> (dtype, trailing shape), as the writer was given them
    shuffled : the datasets stored shuffled
    chunk : the writer's chunk rows
    chunk_rows : per dataset, fewer rows a chunk (the writer's ``chunk_rows``)
    """
    group, steps = chunk_steps(size, shapes, chunk, chunk_rows)
    rows = len(block[next(iter(shapes))])
    aligned = offset % group == 0 and (rows % group == 0 or offset + rows == size)
    if not aligned or any(group % step for step in steps.values()):
        return None
    if not deflate_matches_hdf5():
        return None
    return {
        name: Deflated(
            rows,
            tuple(
                deflated(chunk_, name in shuffled)
                for chunk_ in whole_chunks(np.asarray(block[name], dtype=dtype), steps[name])
            ),
        )
        for name, (dtype, _) in shapes.items()
    }


class SplitWriter:
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

    large_attrs : write the file in the HDF5 1.8 format, whose (dense) attribute storage takes
    attributes beyond the 64 KB an object header message holds; the earliest format refuses
    them. Chosen by itself when ``attrs`` need it; pass ``not attrs_fit(...)`` for attributes
    set after the rows. Only then, so that every file whose attributes fit keeps its bytes.

    Each whole chunk is shuffled and compressed here (:func:`deflated`) and written with
    ``write_direct_chunk``, the bytes HDF5's filters would store (checked once a process by
    :func:`deflate_matches_hdf5`, else HDF5 filters them): h5py's own path copied each chunk
    through HDF5's type conversion and filter pipeline, 1.1x the time (32.8 against 29.6 us a
    sample, docs/performance.md). A block may also come compressed already
    (:func:`deflated_block`, by a worker process): its chunks are stored as they are, in the
    same order, so the file's bytes are the same.
    """

    def __init__(
        self,
        path: Path,
        size: int,
        shapes: dict[str, tuple[str, tuple]],
        attrs: dict,
        shuffled: frozenset[str] = frozenset(),
        chunk: int = CHUNK_SAMPLES,
        large_attrs: bool = False,
        chunk_rows: dict[str, int] | None = None,
    ):
        self.size = size
        self.chunk, steps = chunk_steps(size, shapes, chunk, chunk_rows)  # (full sweeps: a frame)
        self.written = 0
        self.pending: dict[str, list[np.ndarray]] = {name: [] for name in shapes}
        self.path = Path(path)
        self.file = h5py.File(
            path,
            "w",
            libver=("v108" if large_attrs or not attrs_fit(attrs) else "earliest", "v110"),
            track_order=False,
            rdcc_nbytes=0,
        )
        self.datasets = {}
        self.shuffled = shuffled
        self.direct = deflate_matches_hdf5()
        for name, (dtype, tail) in shapes.items():
            shape = (size, *tail)
            self.datasets[name] = self.file.create_dataset(
                name,
                shape=shape,
                dtype=dtype,
                chunks=(steps[name], *shape[1:]),
                compression="gzip",
                compression_opts=1,
                shuffle=name in shuffled,
                track_times=False,
            )
        for key, value in attrs.items():
            self.file.attrs[key] = value

    def append(self, block: dict[str, np.ndarray] | dict[str, Deflated]) -> None:
        """Add the next rows (in file order): one array per dataset, equally long, or the
        :class:`Deflated` rows of every dataset (:func:`deflated_block`)."""
        if isinstance(next(iter(block.values())), Deflated):
            self._append_deflated(block)
            return
        for name in self.pending:
            self.pending[name].append(block[name])
        first = next(iter(self.pending))
        ready = sum(len(v) for v in self.pending[first])
        while ready >= self.chunk or (ready and self.written + ready == self.size):
            rows = min(self.chunk, ready)
            for name, parts in self.pending.items():
                block = np.concatenate(parts)
                with self._failing():
                    self._write(name, block[:rows])
                self.pending[name] = [block[rows:]]
            self.written += rows
            ready -= rows

    def _append_deflated(self, block: dict[str, Deflated]) -> None:
        """Store compressed chunks as :meth:`append` would store their rows: a group of
        ``self.chunk`` rows at a time, every dataset's chunks of the group in turn."""
        rows = block[next(iter(self.pending))].rows
        waiting = any(len(part) for parts in self.pending.values() for part in parts)
        if not self.direct or waiting or self.written % self.chunk:
            raise RuntimeError(f"{self.path}: compressed rows at row {self.written}")
        start = self.written
        for first in range(0, rows, self.chunk):
            stop = min(first + self.chunk, rows)
            for name in self.pending:
                data = self.datasets[name]
                step, tail = data.chunks[0], (0,) * (data.ndim - 1)
                with self._failing():
                    for index in range(first // step, -(-stop // step)):
                        data.id.write_direct_chunk(
                            (start + index * step, *tail), block[name].chunks[index]
                        )
            self.written = start + stop

    def _write(self, name: str, rows: np.ndarray) -> None:
        """Write ``rows`` of dataset ``name`` from row ``self.written``: whole chunks (the last
        of the dataset padded with zeros, HDF5's fill value, as HDF5 stores it)."""
        data = self.datasets[name]
        step = data.chunks[0]
        if not self.direct or self.written % step:
            data[self.written : self.written + len(rows)] = rows
            return
        rows = np.asarray(rows, dtype=data.dtype)
        tail = (0,) * (rows.ndim - 1)
        for index, chunk in enumerate(whole_chunks(rows, step)):
            data.id.write_direct_chunk(
                (self.written + index * step, *tail), deflated(chunk, name in self.shuffled)
            )

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
            cause = os.strerror(code) if code else first_line(exc)
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
        except Exception:  # a failed flush of a file about to be deleted
            pass
