"""How a split's datasets are stored (issue 40, items 1 and 3): only in the file's own bytes,
contiguous or in chunks, as the writers store them.

Attack list (each file built by the test from a real dataset, its card and SHA256SUMS made to
agree, so that the storage is the only problem):
* ``delays`` stored in an external file (``create_dataset(..., external=...)``): a secrets file
  that ``load_split`` returned as samples; pointed at ``/dev/zero`` it kept verify spinning;
* ``delays`` a virtual dataset (VDS) mapped from another file;
* ``labels`` in compact storage (simlidar never writes it);
* ``labels`` asking for an HDF5 filter that is not gzip or shuffle (an unknown plugin, 32004);
* every dataset in one gzip chunk of 262,144 samples (256 MiB of delays inflated for any row);
* a sweep's ``frames.h5`` with an external dataset, read by ``simlidar convert kitti``.
Each is refused by verify (one ``FAILED`` line naming the dataset), by the readers before any
data is read, and by pack (nothing written).
"""

import json
import re
import shutil
import zlib
from pathlib import Path

import h5py
import numpy as np
import pytest

from simlidar.data import load_split
from simlidar.dataset.reader import read_split_info
from simlidar.dataset.storage import MAX_CHUNK_BYTES
from simlidar.errors import DatasetError
from simlidar.release.archive import pack
from simlidar.release.verify import verify


@pytest.fixture
def copy(datasets, tmp_path):
    """A writable copy of the small noise-0.1 dataset."""
    target = tmp_path / datasets[0.1].name
    shutil.copytree(datasets[0.1], target)
    return target


def _refused_everywhere(copy, tmp_path, cli, message):
    """verify names ``message`` in one FAILED line; the readers and pack refuse with it."""
    result = cli("verify", copy)
    assert result.exit_code == 1
    failed = [line for line in result.output.splitlines() if message in line]
    assert len(failed) == 1 and failed[0].startswith("FAILED "), result.output
    with pytest.raises(DatasetError, match=re.escape(message)):
        read_split_info(copy / "train.h5")
    with pytest.raises(DatasetError, match=re.escape(message)):
        load_split(copy)
    with pytest.raises(DatasetError, match=re.escape(message)):
        pack(copy, tmp_path / "out")
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


def test_external_storage_is_refused_and_the_named_file_never_read(copy, tmp_path, cli, agreeing):
    secret = tmp_path / "secret"
    with h5py.File(copy / "train.h5", "a") as f:
        shape, dtype = f["delays"].shape, f["delays"].dtype
        secret.write_bytes(np.full(shape, 0.5, dtype).tobytes())  # "the secret", as samples
        del f["delays"]
        f.create_dataset("delays", shape, dtype, external=[(str(secret), 0, secret.stat().st_size)])
    agreeing(copy)
    message = f"'delays' is stored in the external file '{secret}'"
    assert any(message in p for p in verify(copy))
    _refused_everywhere(copy, tmp_path, cli, message)


def test_a_virtual_dataset_is_refused(copy, tmp_path, cli, agreeing):
    other = tmp_path / "other.h5"
    with h5py.File(copy / "train.h5", "a") as f:
        with h5py.File(other, "w") as o:
            o["delays"] = f["delays"][:]
        layout = h5py.VirtualLayout(f["delays"].shape, f["delays"].dtype)
        layout[:] = h5py.VirtualSource(str(other), "delays", shape=f["delays"].shape)
        del f["delays"]
        f.create_virtual_dataset("delays", layout)
    agreeing(copy)
    _refused_everywhere(copy, tmp_path, cli, "'delays' is an HDF5 virtual dataset")


def test_compact_storage_is_refused(copy, tmp_path, cli, agreeing):
    with h5py.File(copy / "train.h5", "a") as f:
        labels = f["labels"][:]
        del f["labels"]
        dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
        dcpl.set_layout(h5py.h5d.COMPACT)
        space = h5py.h5s.create_simple(labels.shape)
        h5py.h5d.create(f.id, b"labels", h5py.h5t.STD_I64LE, space, dcpl)
        f["labels"][:] = labels
    agreeing(copy)
    _refused_everywhere(copy, tmp_path, cli, "'labels' has compact storage")


def test_a_filter_simlidar_never_writes_is_refused_by_name(copy, tmp_path, cli, agreeing):
    with h5py.File(copy / "train.h5", "a") as f:
        labels = f["labels"][:]
        del f["labels"]
        dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
        dcpl.set_chunk(labels.shape)
        dcpl.set_filter(32004, h5py.h5z.FLAG_OPTIONAL)  # a plugin (lz4) HDF5 would look for
        space = h5py.h5s.create_simple(labels.shape)
        h5py.h5d.create(f.id, b"labels", h5py.h5t.STD_I64LE, space, dcpl)
        f["labels"][:] = labels
    agreeing(copy)
    _refused_everywhere(copy, tmp_path, cli, "'labels' asks for HDF5 filter 32004")


def test_one_huge_chunk_is_refused_before_it_is_inflated(copy, tmp_path, cli, agreeing):
    """Every dataset one gzip chunk of 262,144 samples of zeros (a file of about 3 MB; 256 MiB
    of delays inflated to read any row of it)."""
    n = 262_144
    packed = {}
    with h5py.File(copy / "train.h5", "a") as f:
        for name in list(f):
            dtype, tail = f[name].dtype, f[name].shape[1:]
            del f[name]
            ds = f.create_dataset(
                name, (n, *tail), dtype, chunks=(n, *tail), compression="gzip", shuffle=True
            )
            nbytes = n * int(np.prod(tail)) * dtype.itemsize
            if nbytes not in packed:  # zeros, gzip level 1, a MiB at a time
                gz, block = zlib.compressobj(1), bytes(min(nbytes, 1 << 20))
                packed[nbytes] = b"".join(gz.compress(block) for _ in range(nbytes // len(block)))
                packed[nbytes] += gz.flush()
            ds.id.write_direct_chunk((0,) * (1 + len(tail)), packed[nbytes])
    agreeing(copy)
    assert (copy / "train.h5").stat().st_size < 8_000_000
    assert MAX_CHUNK_BYTES == 128 * 2**20
    message = (
        "'clean_delays' is stored in chunks of (262144, 16, 16) float32 (256.0 MiB each); "
        "expected chunks of at most 128.0 MiB"
    )
    assert any(message in p for p in verify(copy)), verify(copy)
    _refused_everywhere(copy, tmp_path, cli, message)


def test_a_sweep_with_external_storage_is_refused_by_convert_kitti(tmp_path, cli):
    done = cli("sweep", "--frames", 2, "--out", tmp_path / "sweeps", "--json")
    assert done.exit_code == 0, done.output
    frames = Path(json.loads(done.stdout)["path"]) / "frames.h5"
    elsewhere = tmp_path / "labels.bin"
    with h5py.File(frames, "a") as f:
        labels = f["labels"][:]
        elsewhere.write_bytes(labels.tobytes())
        del f["labels"]
        f.create_dataset(
            "labels", labels.shape, labels.dtype, external=[(str(elsewhere), 0, labels.nbytes)]
        )
    result = cli("convert", "kitti", frames.parent, "--out", tmp_path / "crops")
    assert result.exit_code == 1
    assert result.output.strip().splitlines() == [
        f"Error: {frames}: 'labels' is stored in the external file '{elsewhere}'; expected a "
        "dataset whose bytes are in the file, contiguous or chunked"
    ]
    assert not (tmp_path / "crops").exists() or not any((tmp_path / "crops").iterdir())
