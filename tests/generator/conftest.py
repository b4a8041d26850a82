"""Fixtures of the generator's tests: small `sensor` profile datasets made and read back, and a
catalog whose first layout is a wall across the road (the motion checks derived by hand)."""

import hashlib

import h5py
import pytest

from simlidar.generator.config import GeneratorConfig
from simlidar.generator.generate import generate
from simlidar.generator.profiles import load_profile


@pytest.fixture(scope="session")
def sensor_dataset(catalog):
    """make(out, **options): the path of a `sensor` profile dataset of 64 / 32 samples at
    noise 0.1 written under ``out``; ``options`` are GeneratorConfig fields, and
    ``batch_size`` / ``workers`` go to generate (they do not change the bytes)."""

    def make(out, **options):
        run = {k: options.pop(k) for k in ("batch_size", "workers") if k in options}
        config = GeneratorConfig.from_profile(
            load_profile("sensor"), train_size=64, test_size=32, **options
        )
        (written,) = generate(config, [0.1], catalog, out, progress=False, preview=False, **run)
        return written.path

    return make


@pytest.fixture(scope="session")
def read_split():
    """read(path, split="train"): every dataset of a split file and its attributes."""

    def read(path, split="train"):
        with h5py.File(path / f"{split}.h5") as f:
            return {name: f[name][:] for name in f}, dict(f.attrs)

    return read


@pytest.fixture(scope="session")
def dataset_digest():
    """digest(path): sha256 of a dataset's two split files and card, in that order."""

    def digest(path):
        files = ("train.h5", "test.h5", "README.md")
        return hashlib.sha256(b"".join((path / n).read_bytes() for n in files)).hexdigest()

    return digest


@pytest.fixture(scope="session")
def copy_dataset():
    """copy(path, to): ``to`` made, holding a copy of the dataset folder's files (to tamper
    with)."""

    def copy(path, to):
        to.mkdir()
        for item in path.iterdir():
            (to / item.name).write_bytes(item.read_bytes())
        return to

    return copy


@pytest.fixture(scope="session")
def refused():
    """check(result, out, expected): a CLI run refused with exit code 2, ``expected`` in its
    output, one line on stderr and nothing written at ``out``."""

    def check(result, out, expected):
        assert result.exit_code == 2 and expected in result.output, result.output
        assert len(result.stderr.strip().splitlines()) == 1 and not out.exists()

    return check


# class 0's layout replaced by a road and a wall whose face stands across it at x = 20 m: the
# scene of the motion checks derived by hand (a car at 10 m/s before a wall)
WALL_LAYOUT = """description = "A road, and a wall across it 20 m ahead."

[[primitive]]
kind = "box"
surface = "road"
at = [65.0, 0.0, -0.3]
size = [150.0, 14.0, 0.3]

[[primitive]]
kind = "box"
surface = "wall"
at = [20.5, 0.0, 0.0]
size = [1.0, 100.0, 10.0]
"""


@pytest.fixture
def wall_catalog(catalog_copy):
    """The shipped catalog with its first layout (class 0's) a wall across the road at 20 m."""
    from simlidar.scene.recipe import load_catalog

    (catalog_copy / "layouts" / "tunnel.toml").write_text(WALL_LAYOUT)
    (catalog_copy / "sensors" / "hdl64e.toml").unlink()  # its ranges of the tunnel's parameters
    return load_catalog(catalog_copy)
