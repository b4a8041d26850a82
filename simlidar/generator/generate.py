"""Writing dataset directories: splits, preview, card, Croissant metadata and checksums for
every noise level, atomically.

The scenes are simulated once per batch and written to every noise level's files, so
``--noise 0.1,0.2`` gives datasets with the same scenes and different noise. Each dataset is
built under a hidden temporary name beside its final one and renamed into place when complete;
on any failure the temporary folders are removed and nothing appears under a final name.
"""

import multiprocessing
from collections import deque
from concurrent.futures.process import BrokenProcessPool
from contextlib import ExitStack, closing
from dataclasses import dataclass
from functools import partial
from itertools import islice
from pathlib import Path

from simlidar.atomic import Temporary, claim_folder, install
from simlidar.dataset.reader import read_split
from simlidar.dataset.shards import SHARD_SAMPLES
from simlidar.dataset.version import dataset_version
from simlidar.errors import ConfigError, DatasetError
from simlidar.generator.config import GeneratorConfig
from simlidar.generator.generated_card import generated_card, generated_croissant
from simlidar.generator.returns import check_physics, receiver_physics
from simlidar.generator.reuse import differs
from simlidar.generator.sequences import check_window_motion
from simlidar.generator.shard import compressed_rows, remove_partials, split_shards, write_shard
from simlidar.generator.simulate import class_plan, simulate
from simlidar.processes import capped_workers, forked_pool
from simlidar.release.card import write_card
from simlidar.release.checksums import write_sums
from simlidar.release.croissant import write_croissant
from simlidar.release.preview import draw_preview, write_preview
from simlidar.resources import check_disk
from simlidar.scene.recipe import Catalog
from simlidar.sensor.raycast import MAX_BATCH

BATCH = 1024  # samples ray-cast together by default (does not change the data)
# Bytes on disk per pulse of a sample, every dataset of a split file together: measured 3.3
# (physical profile, noise 0) to 5.5 (scan timing) over the shipped profiles; the noisy
# delays, float32, barely compress
DISK_BYTES_PER_PULSE = 4
WAVEFORM_BATCH_BYTES = 256 * 2**20  # stored waveforms a batch holds in memory, at most
# a stored waveform's bytes a pulse on disk: 32 measured (VLP-16, sensor profile, 1 ns bins,
# 668 samples: gzip of a waveform that is zero but near its echoes), doubled as a margin
WAVEFORM_DISK_BYTES_PER_PULSE = 64
# (config, catalog, packing) of the batches the worker processes simulate
_SHARED: tuple | None = None


def _simulate_job(job: tuple[str, int, int]):
    config, catalog, packing = _SHARED
    samples = simulate(config, catalog, *job)
    return samples if packing is None else packing(job, samples)


def _draw_preview(temp: Path, title: str) -> None:
    draw_preview(read_split(temp, "test"), "test", temp / "preview.png", title)


class Previews:
    """Every dataset's preview.png (its test split, :func:`draw_preview`), drawn
    by a forked process of its own from the moment it is made: :func:`generate` writes the
    test split first and makes this object before the train split, so the drawing (0.7 s,
    most of it matplotlib's import and layout, a fixed cost that was the serial tail's
    largest part) overlaps the train split's simulation wherever a second core is free.
    Fork it while no HDF5 file is open. ``wait`` raises the drawing's error, or a
    DatasetError where the process died; ``close`` stops it."""

    def __init__(self, temps: list[Path], titles: list[str]):
        self.pool = forked_pool(1)
        self.futures = [
            self.pool.submit(_draw_preview, temp, title) for temp, title in zip(temps, titles)
        ]

    def wait(self) -> None:
        try:
            for future in self.futures:
                future.result()
        except BrokenProcessPool:
            raise DatasetError(
                "the process drawing preview.png died (killed, or out of memory); nothing was "
                "kept: run the command again"
            ) from None

    def close(self) -> None:
        self.pool.shutdown(wait=True, cancel_futures=True)


class Batches:
    """The Samples of ``jobs`` (split, start, stop), in order. With ``workers`` > 1 forked
    processes simulate them (the scene catalog is shared by the fork: its compiled expressions
    do not pickle), at most two batches a worker ahead of the consumer, so memory stays flat in
    the number of samples. A worker's error is raised by ``next``; a worker that dies (killed,
    out of memory) ends the run with a DatasetError, never a wait without end; a worker whose
    parent dies (``kill -9``) dies with it. The workers are forked when this object is made,
    from the calling thread, which must outlive them: make it before opening any file or lock
    they must not hold (a forked child shares the parent's HDF5 file locks). ``close`` stops
    them. ``workers`` is capped at the batches and the cores (a one-line warning then says
    so). ``packing``, where given, is called by a worker with each job and its Samples, and
    what it returns is what ``next`` gives in their place (:func:`compressed_rows`: the
    compression then runs in the workers, not in the one process that writes)."""

    def __init__(
        self,
        config: GeneratorConfig,
        catalog: Catalog,
        jobs: list,
        workers: int = 1,
        packing=None,
    ):
        global _SHARED
        self.config, self.catalog = config, catalog
        self.todo = iter(jobs)
        self.pending: deque = deque()
        self.pool = None
        workers = capped_workers(workers, len(jobs), "batches") if workers > 1 else 1
        if workers > 1:
            _SHARED = (config, catalog, packing)
            self.pool = forked_pool(workers)
            for job in islice(self.todo, 2 * workers):  # forks every worker now
                self.pending.append((job, self.pool.submit(_simulate_job, job)))

    def __iter__(self):
        return self

    def __next__(self):
        if self.pool is None:
            job = next(self.todo)
            return simulate(self.config, self.catalog, *job)
        if not self.pending:
            raise StopIteration
        job, future = self.pending.popleft()
        try:
            if future is None:  # the pool was already broken when this job was submitted
                raise BrokenProcessPool(job)
            samples = future.result()
        except BrokenProcessPool:
            split, start, stop = job
            raise DatasetError(
                f"a worker process died while simulating {split} samples {start}..{stop - 1} "
                "(killed, or out of memory); nothing was kept: run the command again"
            ) from None
        following = next(self.todo, None)
        if following is not None:
            try:
                future = self.pool.submit(_simulate_job, following)
            except BrokenProcessPool:  # a worker died after this result: the next call says so
                future = None
            self.pending.append((following, future))
        return samples

    def close(self) -> None:
        global _SHARED
        if self.pool is not None:
            self.pool.shutdown(wait=True, cancel_futures=True)
            self.pool = None
            _SHARED = None


@dataclass(frozen=True)
class Written:
    path: Path
    noise: float
    classes: int
    splits: dict[str, int]
    kept: bool = False  # already there, the same dataset (simlidar.generator.reuse)


def _bytes_per_pulse(config: GeneratorConfig) -> int:
    return DISK_BYTES_PER_PULSE + (WAVEFORM_DISK_BYTES_PER_PULSE if config.waveform_bins else 0)


def expected_bytes(config: GeneratorConfig, datasets: int = 1) -> int:
    """About the bytes that ``datasets`` dataset directories of ``config`` take on disk."""
    samples = config.train_size + config.test_size
    return datasets * samples * config.sensor.beams * config.width * _bytes_per_pulse(config)


def check_disk_space(config: GeneratorConfig, datasets: int, out: str | Path) -> None:
    """Refuse to start writing ``datasets`` dataset directories of ``config`` into ``out``
    when its disk has less free space than they take (a ResourceError naming both figures)."""
    samples = config.train_size + config.test_size
    check_disk(
        out,
        expected_bytes(config, datasets),
        f"{datasets} dataset(s) of {samples} samples of {config.sensor.beams} x "
        f"{config.width} pulses ({_bytes_per_pulse(config)} bytes a pulse)",
    )


def generated_name(config: GeneratorConfig) -> str:
    """``simlidar-<classes>c-noise<level>-<profile>[-<sensor>][-scan][-fog<V>][-rain<R>][-beam<Q>][-<mode>][-wave<ns>][-ego<v>][-yaw<w>][-moving][-var<v>][-shift<s>]-v<version>``,
    numbers as Python's repr (0.2, 0.33); ``-<sensor>`` names a sensor other than the VLP-16,
    ``-scan`` scan timing, ``-fog`` a fog's visibility in metres, ``-rain`` a rain's rate in
    mm/h, ``-beam`` a beam footprint's rings of sub-rays, ``-last`` / ``-dual`` a return mode
    other than strongest, ``-wave`` a stored waveform's bin in ns, ``-ego`` / ``-yaw`` the
    ego's speed (m/s) and yaw rate (deg/s), ``-moving`` moving objects, ``-var`` and
    ``-shift`` values that differ from the profile's own."""
    over = config.overrides
    sensor = f"-{config.sensor.name}" if config.sensor.name != "vlp16" else ""
    sensor += ("-scan" if config.timing == "scan" else "") + config.receiver_tag
    sensor += config.motion_tag
    variation = f"-var{float(over['variation'])!r}" if "variation" in over else ""
    shift = f"-shift{float(over['shift_max'])!r}" if "shift_max" in over else ""
    return (
        f"simlidar-{config.classes}c-noise{float(config.noise)!r}-{config.profile_name}"
        f"{sensor}{variation}{shift}-v{dataset_version(config)}"
    )


def checked_request(
    config: GeneratorConfig, catalog: Catalog, batch_size: int, workers, shard_samples
) -> int:
    """Refuse, before anything touches the disk, a batch size, worker count or shard size out
    of range, classes the catalog (the sensor's, ``Catalog.for_sensor``) cannot give and a
    receiver that does not fit the sensor and the catalog; the batch size to use (a batch's
    stored waveforms held at once: at most :data:`WAVEFORM_BATCH_BYTES`).

    config : the request (its classes, sensor, profile's receiver, return mode, waveform bins)
    catalog : the scene recipes, the sensor's part (``Catalog.for_sensor``)
    batch_size : samples simulated at a time, 1 .. :data:`MAX_BATCH`
    workers : processes that simulate batches, an int of at least 1
    shard_samples : samples a shard file holds at most, an int of at least 1
    """
    if not 1 <= batch_size <= MAX_BATCH:
        raise DatasetError(f"batch_size={batch_size}: expected 1..{MAX_BATCH}")
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ConfigError(f"workers={workers!r}: expected a number of processes >= 1")
    if isinstance(shard_samples, bool) or not isinstance(shard_samples, int) or shard_samples < 1:
        raise ConfigError(f"shard_samples={shard_samples!r}: expected a number of samples >= 1")
    class_plan(catalog, config.classes)
    if config.moves:
        check_window_motion(config, catalog)
        batch_size = min(batch_size, MAX_BATCH // 2)  # cast_moving's grid cells
    if config.receiver is not None:
        physics = receiver_physics(config.profile)
        check_physics(physics, config.sensor, catalog.surfaces, config.return_mode)
    if config.waveform_bins:
        per_sample = config.sensor.beams * config.width * config.waveform_bins * 4
        batch_size = max(1, min(batch_size, WAVEFORM_BATCH_BYTES // per_sample))
    return batch_size


def write_local(
    configs, catalog, shards, temps, batches, batch_size, on_rows, stack, titles=None
) -> Previews | None:
    """Write every shard of every noise level's dataset (``configs``, into ``temps``) from
    ``batches``, in order (the test split first); with ``titles``, start drawing each dataset's
    preview once the test split is written (:class:`Previews`, entered into ``stack``) and
    return it (where processes cannot be forked, None: the caller draws it at the end).

    catalog : the scene recipes, the sensor's part, recorded in every file's attributes
    shards : every file of every split (:func:`~simlidar.generator.shard.split_shards`), the
        test split's first, in the order of ``batches``' jobs
    batches : the :class:`Batches` of every shard's jobs, in order; closed once all are written
    batch_size : samples a batch, as ``batches``' jobs were cut (``Shard.batches``)
    on_rows : told the samples written after each batch (the progress bar's update)
    """
    previews = None
    last_test = [shard for shard in shards if shard.split == "test"][-1]
    fork = "fork" in multiprocessing.get_all_start_methods()
    for shard in shards:
        write_shard(configs, catalog, shard, temps, batches, batch_size, on_rows)
        if titles is not None and fork and shard is last_test:  # no file is open now
            previews = stack.enter_context(closing(Previews(temps, titles)))
    batches.close()
    return previews


def finish_dataset(temp: Path, name: str, preview: bool) -> None:
    """What a dataset directory gets once its splits are written: the leftovers of dead
    writers removed, the preview (where ``preview``: not drawn while the splits were written),
    Croissant metadata, the card and SHA256SUMS."""
    remove_partials(temp)
    if preview:
        write_preview(temp, temp / "preview.png", title=name)
    write_croissant(temp, generated_croissant(temp, name))
    write_card(temp, generated_card(temp))
    write_sums(temp)


def generate(
    config: GeneratorConfig,
    noise_levels: list[float],
    catalog: Catalog,
    out: str | Path,
    batch_size: int = BATCH,
    force: bool = False,
    progress: bool = True,
    preview: bool = True,
    workers: int = 1,
    shard_samples: int = SHARD_SAMPLES,
    scheduler: str | None = None,
) -> list[Written]:
    """Generate one dataset directory per noise level under ``out``; return what was written.

    config : what decides the samples (profile, classes, sizes, seed, sensor, timing, receiver,
        weather); its noise is replaced by each of ``noise_levels``
    noise_levels : one dataset per level, each with the same scenes (the noise is drawn apart)
    catalog : the scene recipes (:func:`simlidar.scene.recipe.load_catalog`); the sensor's
        part of it is used and stored
    out : the folder that receives the dataset directories (made if missing)
    batch_size : samples simulated at a time (at most :data:`MAX_BATCH`); no effect on the bytes
    force : replace a dataset directory of the same name; without it, one that is already the
        requested dataset (:func:`simlidar.generator.reuse.differs`) is kept and any other
        is refused (a DatasetError names it and why)
    progress : a progress bar on stderr
    preview : draw each dataset's ``preview.png``
    workers : processes that simulate batches and compress their rows (the calling process
        writes them, in order); the bytes are the same for every count, as every sample draws
        from its own random streams. With ``scheduler`` ``local``: the LocalCluster's worker
        processes
    shard_samples : a split of more samples is written as shard files of this many samples
        (``train-00000-of-00004.h5``, ...; :mod:`simlidar.dataset.shards`); each file is
        written under a hidden name and renamed when complete
    scheduler : a Dask scheduler's address (or ``local``): every file is then one task on the
        cluster, which simulates and writes it into ``out`` (a path every worker must see);
        the same bytes as without (:mod:`simlidar.cluster`)
    """
    from tqdm import tqdm

    catalog = catalog.for_sensor(config.sensor.name)  # what is stored: the recipes used
    batch_size = checked_request(config, catalog, batch_size, workers, shard_samples)
    configs = [config.with_noise(level) for level in noise_levels]
    out = Path(out)
    finals = [out / generated_name(c) for c in configs]
    if len(set(finals)) != len(finals):
        raise DatasetError(f"noise levels {noise_levels}: expected distinct levels")
    levels, kept = [c.noise for c in configs], []
    if not force:
        for final, c in zip(finals, configs):
            if final.exists():
                why = differs(final, c, catalog, shard_samples, preview)
                if why is not None:
                    raise DatasetError(
                        f"{final} already exists and {why}: pass --force to overwrite it"
                    )
                kept.append(Written(final, c.noise, c.classes, dict(c.split_sizes), kept=True))
        todo = [(f, c) for f, c in zip(finals, configs) if not f.exists()]
        if not todo:
            return kept
        finals, configs = [f for f, _ in todo], [c for _, c in todo]
        noise_levels = [c.noise for c in configs]
    check_disk_space(config, len(configs), out)
    shards = split_shards(config, shard_samples)
    if scheduler is None:  # the test split first: its preview is drawn while train is written
        shards = sorted(shards, key=lambda shard: shard.split != "test")
    previews = None
    with ExitStack() as stack:
        if scheduler is not None:
            from simlidar.cluster import LOCAL, connect

            if scheduler == LOCAL:  # one task a file: no more processes than files and cores
                workers = capped_workers(workers, len(shards), "split files")
            client = stack.enter_context(connect(scheduler, workers))
        else:  # batches never straddle two files; forked before any file or lock is open
            jobs = [job for shard in shards for job in shard.batches(batch_size)]
            packing = partial(compressed_rows, configs, shards)
            batches = stack.enter_context(closing(Batches(config, catalog, jobs, workers, packing)))
        created = claim_folder(out)
        claims: list[Temporary] = []
        bar = None
        try:
            for final in finals:
                claims.append(Temporary(out, final.name))
            temps = [c.path for c in claims]
            total = sum(config.split_sizes.values())
            bar = tqdm(
                total=total,
                unit="sample",
                disable=not progress,
                desc="generate",
                dynamic_ncols=True,
            )
            if scheduler is not None:
                from simlidar.generator.on_cluster import write_on_cluster

                write_on_cluster(
                    client, config, noise_levels, catalog, shards, temps, batch_size, bar
                )
            else:
                titles = [final.name for final in finals] if preview else None
                previews = write_local(configs, catalog, shards, temps, batches, batch_size,
                                       bar.update, stack, titles)  # fmt: skip
            bar.close()
            if previews is not None:
                previews.wait()
            for temp, final in zip(temps, finals):
                finish_dataset(temp, final.name, preview and previews is None)
            for claim, final in zip(claims, finals):
                install(claim, final, force)
        except BaseException:
            if bar is not None:
                bar.close()  # the error then gets a line of its own, not the end of the bar's
            raise
        finally:
            stack.close()  # the workers stop before their files are removed
            for claim in claims:
                claim.release()
            if created and out.is_dir() and not any(out.iterdir()):
                out.rmdir()
    made = [Written(f, c.noise, c.classes, dict(c.split_sizes)) for f, c in zip(finals, configs)]
    return sorted(kept + made, key=lambda w: levels.index(w.noise))
