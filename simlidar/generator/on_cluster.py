"""Generation on a Dask cluster (``generate --scheduler``): every split file is one task that
simulates and writes it into the shared output folder (:mod:`simlidar.cluster`)."""

import socket
from pathlib import Path

from simlidar.cluster import run_tasks
from simlidar.content import content_dir
from simlidar.errors import DatasetError
from simlidar.generator.shard import write_shard
from simlidar.generator.simulate import simulate
from simlidar.processes import one_blas_thread
from simlidar.scene.recipe import load_catalog


def write_on_cluster(client, config, noise_levels, catalog, shards, temps, batch_size, bar):
    """Every file as one task on the Dask cluster of ``client``; the bar counts finished files'
    samples.

    config, noise_levels : the request and its noise levels, one dataset each (a task writes
        its file of every level's dataset, :func:`~simlidar.generator.shard.write_shard`)
    catalog : the scene recipes, the sensor's part: each worker loads the same (shipped, or
        from ``catalog.root``) and refuses one of another sha256
    shards : every file of every split (:func:`~simlidar.generator.shard.split_shards`), one
        task each
    temps : each noise level's hidden dataset folder, on a file system every worker shares
    batch_size : samples a task simulates at a time
    """
    shipped = Path(catalog.root).resolve() == content_dir("scenes").resolve()
    where = (None if shipped else str(catalog.root), catalog.fingerprint())
    tasks = [
        (config, list(noise_levels), where, shard, [str(t) for t in temps], batch_size)
        for shard in shards
    ]
    run_tasks(
        client,
        _cluster_shard,
        tasks,
        [f"{s.name} of {', '.join(t.name for t in temps)}" for s in shards],
        lambda index, _: bar.update(shards[index].stop - shards[index].first),
    )


_CATALOGS: dict = {}  # a worker process's scene catalogs, loaded once


def _cluster_shard(config, noise_levels, where, shard, temps, batch_size) -> str:
    """A cluster task: simulate and write one file of every noise level's dataset."""
    root, fingerprint = where
    if where not in _CATALOGS:
        catalog = load_catalog(root).for_sensor(config.sensor.name)
        if catalog.fingerprint() != fingerprint:
            raise DatasetError(
                f"scene catalog {root or '(shipped)'} on worker {socket.gethostname()}: sha256 "
                f"{catalog.fingerprint()}; expected {fingerprint}, the caller's (install the "
                "same simlidar and scene catalog on every worker)"
            )
        _CATALOGS[where] = catalog
    catalog = _CATALOGS[where]
    folders = [Path(t) for t in temps]
    for folder in folders:
        if not folder.is_dir():
            raise DatasetError(
                f"{folder}: not found on worker {socket.gethostname()}; expected the output "
                "folder on a file system that every worker shares"
            )
    configs = [config.with_noise(level) for level in noise_levels]
    one_blas_thread()  # as the forked workers of --workers
    batches = (simulate(config, catalog, *job) for job in shard.batches(batch_size))
    write_shard(configs, catalog, shard, folders, batches, batch_size)
    return shard.name
