"""The split writer compresses whole chunks itself (zlib, HDF5's shuffle) and writes them
with ``write_direct_chunk``: the bytes HDF5's own filters give."""

import h5py
import numpy as np
import pytest

from simlidar.dataset import writer as writer_module
from simlidar.dataset.writer import SplitWriter, deflate_matches_hdf5

SHAPES = {
    "delays": ("float32", (16, 16)),
    "surface": ("uint8", (16, 16)),
    "labels": ("int64", ()),
    "pose": ("float32", (3,)),
    "waveform": ("float32", (2, 3, 5)),
}


def write(path, size, blocks, direct, monkeypatch):
    monkeypatch.setattr(writer_module, "deflate_matches_hdf5", lambda: direct)
    writer = SplitWriter(
        path,
        size,
        SHAPES,
        {"seed": 7},
        shuffled=frozenset({"delays", "pose"}),
        chunk=64,
        chunk_rows={"waveform": 1},
    )
    assert writer.direct is direct
    rng = np.random.default_rng(3)
    for rows in blocks:
        block = {}
        for name, (dtype, tail) in SHAPES.items():
            values = rng.random((rows, *tail)) * 100
            values[values > 70] = 1.0  # runs of one value, as "no return" makes
            block[name] = values.astype(dtype)
        writer.append(block)
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


def test_a_differing_zlib_leaves_the_filters_to_hdf5(monkeypatch):
    """Where this process's zlib does not give HDF5's bytes, the writer does not compress."""
    deflate_matches_hdf5.cache_clear()
    monkeypatch.setattr(writer_module, "deflated", lambda chunk, shuffle: b"other bytes")
    try:
        assert not deflate_matches_hdf5()
    finally:
        deflate_matches_hdf5.cache_clear()
