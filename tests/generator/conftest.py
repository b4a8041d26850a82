"""Fixtures of the generator's tests: small `sensor` profile datasets made and read back."""

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
