"""Shared fixtures: the shipped catalog and a batch of its scenes, small generated datasets, a
writable catalog copy, the command line, a KITTI training folder made from a simulated sweep,
an HTTP server with a packed dataset, synthetic KITTI frames, HDF5 bombs."""

import http.server
import json
import shutil
import threading
from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from simlidar.cli import main
from simlidar.content import content_dir
from simlidar.generator.config import GeneratorConfig
from simlidar.generator.generate import generate
from simlidar.release.archive import pack
from simlidar.scene.build import build_batch
from simlidar.scene.recipe import load_catalog

SMALL = dict(train_size=96, test_size=64)


@pytest.fixture(scope="session")
def catalog():
    return load_catalog()


@pytest.fixture(scope="session")
def small_streams(tmp_path_factory, catalog):
    """A stream dataset of 16 / 8 streams, the default configuration otherwise, made once a
    session for the tests that read it (none may write it)."""
    from simlidar.generator.stream_files import generate_streams

    out = tmp_path_factory.mktemp("small-streams")
    return generate_streams(out, train_size=16, test_size=8, scenes=catalog, progress=False,
                            preview=False)  # fmt: skip


@pytest.fixture(scope="session")
def scene_batch(catalog):
    """``scene_batch(layout, obj, rng)``: the shipped catalog's scenes of these layout and object
    indices (each (n,)), their parameters drawn from ``rng`` (the layouts', then the objects')."""

    def build(layout, obj, rng):
        n = len(layout)
        return build_batch(
            catalog,
            layout,
            obj,
            rng.random((n, catalog.layout_columns)),
            rng.random((n, catalog.object_columns)),
        )

    return build


@pytest.fixture(scope="session")
def small_config():
    return GeneratorConfig(**SMALL)


@pytest.fixture(scope="session")
def datasets(tmp_path_factory, catalog, small_config):
    """Two small 32-class datasets (noise 0.1 and 0.5) of the same scenes: {noise: path}."""
    out = tmp_path_factory.mktemp("data")
    written = generate(small_config, [0.1, 0.5], catalog, out, batch_size=40, progress=False)
    return {w.noise: w.path for w in written}


@pytest.fixture(scope="session")
def sharded(tmp_path_factory, catalog, small_config):
    """The noise-0.1 dataset of ``datasets`` written as shards of 40 samples (train: 3 files,
    test: 2), by two worker processes in batches of 16."""
    out = tmp_path_factory.mktemp("sharded")
    (written,) = generate(
        small_config,
        [0.1],
        catalog,
        out,
        batch_size=16,
        progress=False,
        workers=2,
        shard_samples=40,
    )
    return written.path


@pytest.fixture
def catalog_copy(tmp_path):
    """A writable copy of the shipped scene catalog."""
    root = tmp_path / "scenes"
    shutil.copytree(content_dir("scenes"), root)
    return root


@pytest.fixture
def limited_python():
    """``limited_python(args, nbytes, timeout=300)``: ``python <args>`` in a child process under
    an address-space limit of ``nbytes`` (``ulimit -v``; never above a limit this process
    already has), output captured as text, so that a regression that allocates what a hostile
    input declares fails in the child with a MemoryError instead of taking the machine's
    memory. Returns the ``CompletedProcess``."""
    import resource
    import subprocess
    import sys

    def run(args, nbytes: int, timeout: float = 300):
        hard = resource.getrlimit(resource.RLIMIT_AS)[1]
        soft = nbytes if hard == resource.RLIM_INFINITY else min(nbytes, hard)
        return subprocess.run(
            [sys.executable, *map(str, args)],
            capture_output=True,
            text=True,
            timeout=timeout,
            preexec_fn=lambda: resource.setrlimit(resource.RLIMIT_AS, (soft, hard)),
        )

    return run


@pytest.fixture(scope="session")
def cli():
    """``cli(*args)``: the ``simlidar`` command run in this process (click's ``CliRunner``),
    every argument made a string (paths, numbers); returns click's ``Result``."""

    def invoke(*args):
        return CliRunner().invoke(main, [str(a) for a in args])

    return invoke


class _Handler(http.server.SimpleHTTPRequestHandler):
    release = threading.Event()  # set at teardown so a hanging request ends

    def log_message(self, *args):  # keep the test output clean
        pass

    def do_GET(self):
        if self.path.startswith("/truncated/"):
            body = (Path(self.directory) / self.path.split("/", 2)[2]).read_bytes()
            self.send_response(200)
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body[: len(body) // 2])  # then the connection closes
            self.close_connection = True
            return
        if self.path.startswith("/trickle/"):  # a byte every 0.1 s, for ever
            self.send_response(200)
            self.send_header("Content-Length", "1000000")
            self.end_headers()
            while not self.release.wait(timeout=0.1):
                try:
                    self.wfile.write(b"x")
                    self.wfile.flush()
                except OSError:  # the client gave up
                    return
            return
        if self.path.startswith("/hang/"):
            self.release.wait(timeout=10)  # never answers within the client's timeout
            return
        super().do_GET()


# A DontCare line as KITTI writes them (the real sample's frame 000001 has two): skipped.
DONT_CARE = "DontCare -1 -1 -10 503.89 169.71 590.61 190.13 -1 -1 -1 -1000 -1000 -1000 -10\n"


@pytest.fixture(scope="session")
def built_kitti(tmp_path_factory, cli) -> Path:
    """A KITTI training folder made here, so that the format checks run in any clone: 8 frames
    of an HDL-64E sweep exported in KITTI's layout (`simlidar sweep --export kitti`: label_2/,
    calib/, velodyne/; 6 frames with a car, pedestrian or truck, 2 without), moved under
    ``training/`` without the sweep's frames.h5, so that the converter reads them as recorded
    frames, plus a DontCare line in frame 000002."""

    out = tmp_path_factory.mktemp("built-kitti")
    args = ["sweep", "--frames", "8", "--sensor", "hdl64e", "--export", "kitti"]
    done = cli(*args, "--out", str(out / "sweep"), "--json")
    assert done.exit_code == 0, done.output
    sweep = Path(json.loads(done.stdout)["path"])
    root = out / "kitti"
    (root / "training").mkdir(parents=True)
    for folder in ("label_2", "calib", "velodyne"):
        shutil.move(sweep / folder, root / "training" / folder)
    with (root / "training" / "label_2" / "000002.txt").open("a") as labels:
        labels.write(DONT_CARE)
    shutil.rmtree(out / "sweep")
    return root


@pytest.fixture
def server(tmp_path):
    """(base URL, served folder) of a server that stops when the test ends."""
    root = tmp_path / "www"
    root.mkdir()
    _Handler.release.clear()
    httpd = http.server.ThreadingHTTPServer(
        ("127.0.0.1", 0), lambda *a: _Handler(*a, directory=str(root))
    )
    thread = threading.Thread(target=httpd.serve_forever, args=(0.05,), daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{httpd.server_address[1]}", root
    _Handler.release.set()
    httpd.shutdown()
    httpd.server_close()
    thread.join(timeout=5)


@pytest.fixture
def packed(datasets, server):
    """The small dataset packed into the served folder: (archive, its sha256)."""
    archive, checksum = pack(datasets[0.1], server[1])
    return archive, checksum.read_text().split()[0]


# A calibration whose camera axes are the Velodyne's renamed, as KITTI's nearly are:
# camera x = -velodyne y (right), camera y = -velodyne z (down), camera z = velodyne x (ahead).
SIMPLE_CALIB = """P0: 1 0 0 0 0 1 0 0 0 0 1 0
R0_rect: 1 0 0 0 1 0 0 0 1
Tr_velo_to_cam: 0 -1 0 0 0 0 -1 0 1 0 0 0
"""


def _write_frame(
    root: Path, stem: str, points: np.ndarray, labels: str, calib: str = SIMPLE_CALIB
) -> None:
    """One frame in the benchmark's layout under ``root/training``; points (n, 3) metres."""
    base = root / "training"
    for folder in ("velodyne", "label_2", "calib"):
        (base / folder).mkdir(parents=True, exist_ok=True)
    scan = np.zeros((len(points), 4), dtype="<f4")
    scan[:, :3] = points
    (base / "velodyne" / f"{stem}.bin").write_bytes(scan.tobytes())
    (base / "label_2" / f"{stem}.txt").write_text(labels)
    (base / "calib" / f"{stem}.txt").write_text(calib)


def _wall(x_m: float, ys_m: np.ndarray, zs_m: np.ndarray) -> np.ndarray:
    """Points (n, 3) on the plane x = x_m, one per (y, z) of the two grids."""
    y, z = np.meshgrid(ys_m, zs_m)
    return np.stack([np.full(y.size, x_m), y.ravel(), z.ravel()], axis=1)


@pytest.fixture
def synthetic_kitti(tmp_path) -> Path:
    """Three synthetic frames (SIMPLE_CALIB): 000000 a car 10 m straight behind the sensor
    with a wall of points on its near face at x = -9.5 m, 000001 a pedestrian 5 m ahead with
    a wall at x = 5 m, 000002 no objects (DontCare only)."""
    steps = np.arange(-0.75, 0.8, 0.1)
    # camera (0, 1, -10) = velodyne (-10, 0, -1): the box's bottom centre, 1 m below the sensor
    car = "Car 0.00 0 0.00 0 0 10 10 1.50 1.60 4.00 0.00 1.00 -10.00 0.00\n"
    _write_frame(tmp_path, "000000", _wall(-9.5, 2 * steps, steps), car)
    pedestrian = "Pedestrian 0.50 1 0.00 0 0 10 10 1.80 0.60 0.80 0.00 1.00 5.20 0.00\n"
    _write_frame(tmp_path, "000001", _wall(5.0, steps / 3, steps), pedestrian)
    dont_care = "DontCare -1 -1 -10 1 1 5 5 -1 -1 -1 -1000 -1000 -1000 -10\n"
    _write_frame(tmp_path, "000002", _wall(20.0, steps, steps), dont_care)
    return tmp_path


def _agreeing(copy):
    """Make the card and SHA256SUMS agree with the split files as they now are."""
    from simlidar.release.card import write_card
    from simlidar.release.checksums import write_sums

    with h5py.File(copy / "train.h5", "r") as f:
        size = f["labels"].shape[0]
    card = copy / "README.md"
    write_card(copy, card.read_text().replace("num_examples: 96", f"num_examples: {size}"))
    write_sums(copy)


def _bomb(copy, n=20_000_000, rows=None, stored=False):
    """Every dataset of train.h5 declared with ``n`` rows: contiguous (``rows`` None) or in
    gzip chunks of ``rows`` rows, never written, or (``stored``) each chunk one byte."""
    with h5py.File(copy / "train.h5", "a") as f:
        for name in list(f):
            dtype, tail = f[name].dtype, f[name].shape[1:]
            del f[name]
            options = dict(chunks=(rows, *tail), compression="gzip") if rows else {}
            ds = f.create_dataset(name, shape=(n, *tail), dtype=dtype, **options)
            for start in range(0, n, rows) if stored else ():
                ds.id.write_direct_chunk((start,) + (0,) * len(tail), b"\0")
    _agreeing(copy)


@pytest.fixture
def agreeing():
    """``agreeing(copy)``: make a dataset copy's card and SHA256SUMS agree with its split files
    as they now are (so that a test of a file's content meets no checksum error first)."""
    return _agreeing


@pytest.fixture
def hdf5_bomb():
    """``hdf5_bomb(copy, n=20_000_000, rows=None, stored=False)``: make a dataset copy's
    train.h5 declare ``n`` samples it does not store (the card and sums agreeing)."""
    return _bomb


def pytest_collection_modifyitems(config, items):
    """Mark the tests of tests/slow_tests.py ``slow``: ``python -m pytest -m "not slow"`` is the
    quick run (README, Development); CI runs every test."""
    from slow_tests import SLOW

    for item in items:
        if item.nodeid.split("[")[0] in SLOW:
            item.add_marker(pytest.mark.slow)
