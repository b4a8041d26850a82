"""One file of a split (a shard) of every noise level's dataset: which samples it holds, its
attributes, and its writing under a hidden name, renamed when complete. A local run
(:mod:`simlidar.generator.generate`) and a cluster task (:mod:`simlidar.generator.on_cluster`)
both write through :func:`write_shard`."""

import json
import os
import secrets
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from simlidar import __version__
from simlidar.dataset.schema import (
    SHUFFLED,
    SPLITS,
    WAVEFORM_CHUNK,
    WAVEFORM_SCHEMA,
    generated_shapes,
)
from simlidar.dataset.shards import shard_bounds, split_file_names
from simlidar.dataset.version import dataset_version
from simlidar.dataset.writer import SplitWriter, deflated_block
from simlidar.generator.config import GeneratorConfig
from simlidar.generator.pulses import split_rows
from simlidar.generator.returns import receiver_physics
from simlidar.generator.sequences import motion_attrs
from simlidar.generator.simulate import class_plan
from simlidar.scene.recipe import Catalog
from simlidar.sensor.model import row_order
from simlidar.sensor.rays import column_centres_deg


@dataclass(frozen=True)
class Shard:
    """One file of a split: the samples ``first`` .. ``stop - 1``, written as ``name``."""

    split: str
    index: int
    count: int  # files of the split (1: not sharded)
    first: int
    stop: int
    name: str

    def batches(self, batch_size: int) -> list[tuple[str, int, int]]:
        """The simulation jobs (split, start, stop) of this file, in order."""
        return [
            (self.split, start, min(start + batch_size, self.stop))
            for start in range(self.first, self.stop, batch_size)
        ]


def split_shards(config: GeneratorConfig, shard_samples: int) -> list[Shard]:
    """Every file of every split of ``config``'s datasets, in order."""
    shards = []
    for split in SPLITS:
        size = config.split_sizes[split]
        bounds = shard_bounds(size, shard_samples)
        names = split_file_names(split, size, shard_samples)
        shards += [
            Shard(split, i, len(bounds), first, stop, name)
            for i, ((first, stop), name) in enumerate(zip(bounds, names))
        ]
    return shards


CHUNK_ROWS = {name: WAVEFORM_CHUNK for name in WAVEFORM_SCHEMA}  # the writers' chunk_rows


def _shapes(config: GeneratorConfig) -> dict[str, tuple[str, tuple]]:
    """The datasets of a generated split file of ``config``."""
    return generated_shapes(
        config.sensor.beams,
        config.width,
        config.timing,
        config.receiver is not None,
        config.reported_returns,
        config.waveform_bins,
        config.moves,
    )


def compressed_rows(configs: list[GeneratorConfig], shards: list[Shard], job, samples):
    """A simulated batch (``job``: split, start, stop) as :func:`write_shard` takes it from a
    worker process: every noise level's rows (``configs``), compressed as the writer of the
    batch's file (in ``shards``) would compress them (:func:`~simlidar.dataset.writer.
    deflated_block`), so the compression runs in the worker and the writing process stores
    the chunks as they are, with the same bytes; or ``samples`` as they are where a batch does
    not cover whole chunks (the writer then cuts them)."""
    split, start, _ = job
    shard = next(s for s in shards if s.split == split and s.first <= start < s.stop)
    shapes, blocks = _shapes(configs[0]), []
    for cfg in configs:
        block = deflated_block(
            split_rows(samples, cfg),
            start - shard.first,
            shard.stop - shard.first,
            shapes,
            SHUFFLED,
            chunk_rows=CHUNK_ROWS,
        )
        if block is None:
            return samples
        blocks.append(block)
    return blocks


def write_shard(
    configs: list[GeneratorConfig],
    catalog: Catalog,
    shard: Shard,
    temps: list[Path],
    batches,
    batch_size: int,
    on_rows=lambda rows: None,
) -> None:
    """Write ``shard`` of every noise level's dataset (``configs``, into the folders ``temps``)
    from ``batches``, an iterator of its simulated batches in order. Each file is written
    under a hidden name of its own and renamed when complete; on any error the hidden files
    are removed.

    catalog : the scene recipes, the sensor's part, recorded in every file's attributes
    batch_size : samples a batch, as ``batches`` was cut (:meth:`Shard.batches`)
    on_rows : told the samples written after each batch (a progress bar's update; by default
        nothing)
    """
    shapes = _shapes(configs[0])
    token = secrets.token_hex(4)  # two runs of one shard (a retried task) never share a file
    writers: list[SplitWriter] = []
    try:
        for cfg, temp in zip(configs, temps):
            attrs = generated_split_attrs(cfg, catalog, shard.split)
            if shard.count > 1:  # a shard's own attributes (a one-file split has none)
                attrs |= {"shard": shard.index, "shards": shard.count}
            hidden = temp / f".{shard.name}.partial-{token}"
            writers.append(
                SplitWriter(
                    hidden,
                    shard.stop - shard.first,
                    shapes,
                    attrs,
                    SHUFFLED,
                    chunk_rows=CHUNK_ROWS,
                )  # fmt: skip
            )
        for _, start, stop in shard.batches(batch_size):
            samples = next(batches)  # or, from a worker, the rows already compressed
            blocks = samples if isinstance(samples, list) else (
                split_rows(samples, cfg) for cfg in configs
            )  # fmt: skip
            for block, writer in zip(blocks, writers):
                writer.append(block)
            on_rows(stop - start)
        for writer, temp in zip(writers, temps):
            writer.close()
            os.replace(writer.path, temp / shard.name)  # complete: under its own name
    except BaseException:
        for writer in writers:
            writer.abort()
            writer.path.unlink(missing_ok=True)
        raise


def remove_partials(temp: Path) -> None:
    """Remove the hidden files of shards whose writers died (their shards were written again)."""
    for leftover in temp.glob(".*.partial-*"):
        leftover.unlink(missing_ok=True)


def generated_split_attrs(config: GeneratorConfig, catalog: Catalog, split: str) -> dict:
    """The attributes of one split file (documented in docs/dataset-format.md)."""
    plan = class_plan(catalog, config.classes)
    sensor = config.sensor
    rows = row_order(sensor)
    strings = h5py.string_dtype()
    attrs = {
        "dataset_version": dataset_version(config),
        "simlidar_version": __version__,
        "split": split,
        "config": config.to_json(),
        "seed": config.seed,
        "noise": float(config.noise),
        "classes": plan.classes,
        "class_mode": plan.mode,
        "class_names": np.array(plan.names, dtype=strings),
        "layout_names": np.array(catalog.layout_names, dtype=strings),
        "object_names": np.array(catalog.object_names, dtype=strings),
        "surface_names": np.array(catalog.surfaces, dtype=strings),
        "sensor": json.dumps(sensor.to_dict(), sort_keys=True),
        "catalog": json.dumps(catalog.to_dict(), sort_keys=True),
        "catalog_sha256": catalog.fingerprint(),
        "row_laser_ids": np.array(rows, dtype=np.int32),
        "row_elevation_deg": np.array([sensor.elevations_deg[r] for r in rows]),
        "column_azimuth_deg": column_centres_deg(config.width, config.fov_deg),
        "tof_max_ns": sensor.tof_max_ns,
        "no_return_delay": 1.0,
        "min_object_hits": config.min_object_hits,
    }
    if config.profile is not None:  # absent: the physical rule (and 1.0.0's bytes)
        rule = config.pulse_rule
        attrs["profile"] = config.profile.name
        attrs["no_return_delay"] = rule["missing_delay"]
        attrs["noise_on"] = rule["noise_on"]
        attrs["input_spikes"] = rule["spikes"]
    if config.timing == "scan":  # absent: flash (and the bytes of flash datasets)
        attrs["timing"] = "scan"
        attrs["delay_unit_ns"] = config.scan_window_ns
    if config.receiver is not None:  # absent: every hit in range returns (the other profiles)
        attrs |= receiver_physics(config.profile).attrs()
    if config.full_waveform:  # absent: one ray a pulse, its strongest return (4.0.0's bytes)
        attrs["beam_samples"] = config.beam_samples
        attrs["return_mode"] = config.return_mode
    if config.waveform_bins:
        attrs["waveform_bin_ns"] = config.waveform_bin_ns
        attrs["waveform_bins"] = config.waveform_bins
    return attrs | motion_attrs(config, catalog)
