"""Shared fixtures: the shipped catalog, a small generated dataset, a writable catalog copy."""

import shutil

import pytest

from simlidar.content import content_dir
from simlidar.generator.config import GeneratorConfig
from simlidar.generator.generate import generate
from simlidar.scene.recipe import load_catalog

SMALL = dict(train_size=96, test_size=64)


@pytest.fixture(scope="session")
def catalog():
    return load_catalog()


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
def address_limit():
    """``address_limit(n)``: a ``preexec_fn`` that runs a child process under an address-space
    limit of ``n`` bytes (``ulimit -v``; never above a limit this process already has), so that
    a regression that allocates what a hostile input declares fails in the child with a
    MemoryError instead of taking the machine's memory."""
    import resource

    def limit(nbytes: int):
        hard = resource.getrlimit(resource.RLIMIT_AS)[1]
        soft = nbytes if hard == resource.RLIM_INFINITY else min(nbytes, hard)
        return lambda: resource.setrlimit(resource.RLIMIT_AS, (soft, hard))

    return limit
