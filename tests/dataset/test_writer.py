"""The split writer compresses whole chunks itself (zlib, HDF5's shuffle) and writes them
with ``write_direct_chunk``: the bytes HDF5's own filters give."""

import h5py
import numpy as np
import pytest

from simlidar.dataset import writer as writer_module
from simlidar.dataset.writer import SplitWriter, deflate_matches_hdf5, deflated_block

SHAPES = {
    "delays": ("float32", (16, 16)),
    "surface": ("uint8", (16, 16)),
    "labels": ("int64", ()),
    "pose": ("float32", (3,)),
    "waveform": ("float32", (2, 3, 5)),
}


SHUFFLED = frozenset({"delays", "pose"})


def write(path, size, blocks, direct, monkeypatch, compressed=None):
    """The file of ``blocks`` of random rows; with a list ``compressed``, each block that
    :func:`deflated_block` takes is handed in compressed, its index appended to the list."""
    monkeypatch.setattr(writer_module, "deflate_matches_hdf5", lambda: direct)
    options = {"chunk": 64, "chunk_rows": {"waveform": 1}}
    writer = SplitWriter(path, size, SHAPES, {"seed": 7}, shuffled=SHUFFLED, **options)
    assert writer.direct is direct
    rng = np.random.default_rng(3)
    offset = 0
    for index, rows in enumerate(blocks):
        block = {}
        for name, (dtype, tail) in SHAPES.items():
            values = rng.random((rows, *tail)) * 100
            values[values > 70] = 1.0  # runs of one value, as "no return" makes
            block[name] = values.astype(dtype)
        if compressed is not None:
            ready = deflated_block(block, offset, size, SHAPES, SHUFFLED, **options)
            if ready is not None:
                block = ready
                compressed.append(index)
        writer.append(block)
        offset += rows
    writer.close()
    return path.read_bytes()


def test_this_machines_zlib_gives_hdf5s_bytes():
    assert deflate_matches_hdf5()


@pytest.mark.parametrize(
    ("size", "blocks"),
    [(200, [200]), (200, [7, 100, 93]), (64, [64]), (30, [10, 20])],
)
def test_chunks_compressed_here_are_the_bytes_hdf5_writes(tmp_path, monkeypatch, size, blocks):
    """Whole chunks, the last one short (padded with HDF5's fill value), blocks that straddle
    chunks, a dataset of one-row chunks: the same file, byte for byte, as h5py writing the
    rows through HDF5's filters."""
    ours = write(tmp_path / "ours.h5", size, blocks, True, monkeypatch)
    theirs = write(tmp_path / "theirs.h5", size, blocks, False, monkeypatch)
    assert ours == theirs
    with h5py.File(tmp_path / "ours.h5") as split:
        assert split["delays"].shape == (size, 16, 16)
        assert split["delays"].compression == "gzip" and split["delays"].shuffle


@pytest.mark.parametrize(
    ("size", "blocks", "taken"),
    [
        (200, [64, 128, 8], [0, 1, 2]),  # whole chunks, the last block ends the file
        (200, [7, 57, 64, 72], [2, 3]),  # rows left over, then whole chunks again
        (200, [64, 100, 36], [0]),  # a block ending mid-chunk goes in as rows
        (30, [30], [0]),  # a file shorter than a chunk
    ],
)
def test_rows_compressed_where_they_are_made_are_stored_as_the_rows_would_be(
    tmp_path, monkeypatch, size, blocks, taken
):
    """deflated_block (a worker's compression) takes a block that starts at a whole chunk of
    every dataset and ends at one or at the file's end, and the writer stores its chunks in
    the order it would store the rows: the same file, byte for byte, as the rows written
    through HDF5's filters; any other block is left to the writer."""
    compressed = []
    ours = write(tmp_path / "ours.h5", size, blocks, True, monkeypatch, compressed)
    assert compressed == taken
    theirs = write(tmp_path / "theirs.h5", size, blocks, False, monkeypatch)
    assert ours == theirs


def test_compressed_rows_are_refused_where_the_writer_has_rows_waiting(tmp_path):
    """Compressed chunks after rows that do not fill a chunk would break the file's order:
    refused, naming the file and row."""
    rows = {name: np.zeros((10, *tail), dtype) for name, (dtype, tail) in SHAPES.items()}
    ready = deflated_block(rows, 0, 10, SHAPES, SHUFFLED, chunk=64, chunk_rows={"waveform": 1})
    writer = SplitWriter(tmp_path / "w.h5", 20, SHAPES, {}, shuffled=SHUFFLED, chunk=64)
    writer.append({name: values[:5] for name, values in rows.items()})
    with pytest.raises(RuntimeError, match=r"w\.h5: compressed rows at row 0"):
        writer.append(ready)
    writer.abort()


def test_a_differing_zlib_leaves_the_filters_to_hdf5(monkeypatch):
    """Where this process's zlib does not give HDF5's bytes, the writer does not compress."""
    deflate_matches_hdf5.cache_clear()
    monkeypatch.setattr(writer_module, "deflated", lambda chunk, shuffle: b"other bytes")
    try:
        assert not deflate_matches_hdf5()
    finally:
        deflate_matches_hdf5.cache_clear()
