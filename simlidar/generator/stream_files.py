"""``simlidar stream``: a stream dataset directory (docs/streams.md): ``train.h5`` and
``test.h5`` in the schema of :mod:`simlidar.dataset.stream`, a preview, the card, Croissant
metadata and checksums, written under a temporary name and renamed into place when complete."""

import hashlib
import json
import math
from contextlib import ExitStack
from pathlib import Path

import h5py
import numpy as np

from simlidar.atomic import building
from simlidar.dataset.stream import NAME, SOURCE
from simlidar.dataset.writer import SplitWriter
from simlidar.errors import ConfigError
from simlidar.generator.declared_card import converted_split_attrs, write_release_files
from simlidar.generator.pulse_streams import StreamBatch, simulate_streams
from simlidar.generator.returns import receiver_physics
from simlidar.generator.simulate import class_plan
from simlidar.generator.stream_config import StreamConfig
from simlidar.processes import capped_workers, forked_pool
from simlidar.resources import check_memory
from simlidar.scene.recipe import Catalog, load_catalog
from simlidar.sensor.model import Sensor, load_sensor, row_order, tof_ns
from simlidar.sensor.moving import OBJECT_CELLS
from simlidar.sensor.rays import column_centres_deg

BATCH = 64  # streams cast together by default (does not change the data)
# the per-event datasets, by the StreamBatch field each is made of
EVENT_FIELDS = {
    "event_x": "event_x",
    "event_y": "event_y",
    "event_t_us": "event_t_us",
    "event_range_m": "event_range_m",
    "event_surface": "event_surface",
}


def stream_name(config: StreamConfig) -> str:
    """``simlidar-stream-<classes>c-<rotations>rot-w<width>[-fov<deg>][-<sensor>][-var<v>]
    [-hits<k>][-<profile>][-fog<V>][-rain<R>]-v<version>``: the field of view, sensor,
    variation and object hits where they are not the defaults (36 degrees, the VLP-16, 1, 4),
    the receiver's profile and weather where there is one; the seed, as in generate's names, is
    not named."""
    default = StreamConfig(classes=config.classes, train_size=config.train_size,
                           test_size=config.test_size)  # fmt: skip
    hits = config.min_object_hits
    tag = f"-fov{float(config.fov_deg)!r}" if config.fov_deg != default.fov_deg else ""
    tag += f"-{config.sensor.name}" if config.sensor.name != "vlp16" else ""
    tag += f"-var{float(config.variation)!r}" if config.variation != 1.0 else ""
    tag += f"-hits{hits}" if hits != default.min_object_hits else ""
    receiver = config.receiver_config
    if receiver is not None:
        tag += f"-{receiver.profile_name}{receiver.receiver_tag}"
    return (
        f"simlidar-stream-{config.classes}c-{config.rotations}rot-w{config.width}{tag}"
        f"-v{config.version}"
    )


def scenes_digest(catalog: Catalog) -> str:
    """sha256 of what the streams are made of besides the config: the scene catalog as used
    (the sensor's part) and its scenarios, as stored."""
    both = {"catalog": catalog.to_dict(), "scenarios": catalog.scenarios.source}
    return hashlib.sha256(json.dumps(both, sort_keys=True).encode()).hexdigest()


def stream_split_attrs(config: StreamConfig, catalog: Catalog, split: str) -> dict:
    """The attributes of one stream split file (docs/streams.md)."""
    plan = class_plan(catalog, config.classes)
    sensor = config.sensor
    rows = row_order(sensor)
    strings = h5py.string_dtype()
    attrs = converted_split_attrs(NAME, split, config, plan.names, plan.mode, sensor.to_dict(),
                                  scenes_digest(catalog))  # fmt: skip
    columns = column_centres_deg(config.width, config.fov_deg)
    attrs["dataset_version"] = config.version
    receiver = config.receiver_config
    if receiver is not None:
        attrs |= receiver_physics(receiver.profile).attrs()
    return attrs | {
        "layout_names": np.array(catalog.layout_names, dtype=strings),
        "object_names": np.array(catalog.object_names, dtype=strings),
        "surface_names": np.array(catalog.surfaces, dtype=strings),
        "scenario_names": np.array(catalog.scenarios.names, dtype=strings),
        "scenarios": json.dumps(catalog.scenarios.source, sort_keys=True),
        "catalog": json.dumps(catalog.to_dict(), sort_keys=True),
        "rotations": config.rotations,
        "rotation_us": config.rotation_us,
        "span_us": config.rotations * config.rotation_us,
        "tof_max_ns": sensor.tof_max_ns,
        "row_laser_ids": np.array(rows, dtype=np.int32),
        "row_elevation_deg": np.array([sensor.elevations_deg[r] for r in rows]),
        "column_azimuth_deg": np.tile(columns, config.rotations),
        "min_object_hits": config.min_object_hits,
    }


def dense_delays(batch: StreamBatch, config: StreamConfig) -> np.ndarray:
    """Each pulse's time of flight over ``tof_max_ns`` (1.0: no return), (n, H, R W) float32,
    from the events (an event is a pulse's return; the time of flight is its range's)."""
    sensor = config.sensor
    n = len(batch.labels)
    delays = np.ones((n, sensor.beams, config.rotations * config.width), np.float32)
    sample = np.repeat(np.arange(n), batch.event_count)
    column = batch.event_rotation * config.width + batch.event_x
    tof = tof_ns(batch.event_range_m.astype(np.float64))
    delays[sample, batch.event_y, column] = (tof / sensor.tof_max_ns).astype(np.float32)
    return delays


def _per_sample(batch: StreamBatch, config: StreamConfig, first_event: int) -> dict:
    schema = SOURCE.schema_of(config.profile is not None)
    rows = {
        name: getattr(batch, name)
        for name in schema
        if schema[name][1][0] == "N" and getattr(batch, name, None) is not None
    }
    rows["delays"] = dense_delays(batch, config)
    rows["event_start"] = first_event + np.cumsum(batch.event_count) - batch.event_count
    return rows


# (config, catalog) of the batches forked workers simulate (set before the pool forks)
_SHARED: tuple | None = None


def _simulate_job(job: tuple[str, int, int]) -> StreamBatch:
    config, catalog = _SHARED
    return simulate_streams(config, catalog, *job)


def write_stream_split(path: Path, config: StreamConfig, catalog: Catalog, split: str,
                       batch_size: int, on_rows, pool=None) -> None:  # fmt: skip
    """One split file of ``config``: its streams ``batch_size`` at a time (``on_rows`` told the
    streams done after each batch), the per-sample rows as they come, the events at the end.

    path : the split file to write; catalog : the scene recipes with their scenarios, the
    sensor's part; split : ``train`` or ``test``
    pool : worker processes that simulate the batches (:func:`simlidar.processes.forked_pool`,
        forked after :data:`_SHARED` was set), their batches written in order; None: here
    """
    size = config.split_sizes[split]
    received = config.profile is not None
    schema = SOURCE.schema_of(received)
    event_fields = EVENT_FIELDS | ({"event_intensity": "event_intensity"} if received else {})
    dims = {"H": config.sensor.beams, "W": config.rotations * config.width,
            "R": config.rotations}  # fmt: skip
    shapes = {
        name: (dtype, tuple(dims.get(d, d) for d in shape[1:]))
        for name, (dtype, shape) in schema.items()
        if shape[0] == "N"
    }
    attrs = stream_split_attrs(config, catalog, split)
    writer = SplitWriter(
        path, size, shapes, attrs, frozenset({"delays", "t_visible_us", "t_in_view_us"})
    )
    events: dict[str, list[np.ndarray]] = {name: [] for name in event_fields}
    written = 0
    jobs = [(split, start, min(start + batch_size, size)) for start in range(0, size, batch_size)]
    batches = (simulate_streams(config, catalog, *job) for job in jobs)
    if pool is not None:
        batches = pool.map(_simulate_job, jobs)  # in order
    try:
        for batch in batches:
            writer.append(_per_sample(batch, config, written))
            written += int(batch.event_count.sum())
            for name, field in event_fields.items():
                events[name].append(getattr(batch, field))
            on_rows(len(batch.labels))
        for name, parts in events.items():
            writer.add_rows(name, np.concatenate(parts), schema[name][0])
        writer.add_rows("event_p", np.zeros(written, np.uint8), schema["event_p"][0])
        writer.close()
    finally:
        writer.abort()  # a no-op after close()


def generate_streams(
    out: str | Path = "data",
    classes: int = 4,
    train_size: int = 3000,
    test_size: int = 600,
    seed: int = 0,
    width: int = 32,
    fov_deg: float = 36.0,
    rotations: int = 10,
    min_object_hits: int = 4,
    max_attempts: int = 200,
    variation: float = 1.0,
    sensor: "str | Sensor" = "vlp16",
    profile: str | None = None,
    fog_visibility_m: float = math.inf,
    rain_rate_mm_h: float = 0.0,
    scenes: "str | Path | Catalog | None" = None,
    batch_size: int = BATCH,
    force: bool = False,
    progress: bool = True,
    preview: bool = True,
    workers: int = 1,
) -> Path:
    """Write a stream dataset directory under ``out`` and return its path. The card's
    "Regenerate" calls this with the stored configuration.

    classes, train_size, test_size, seed, width, fov_deg, rotations, min_object_hits,
    max_attempts, variation, sensor, profile, fog_visibility_m, rain_rate_mm_h :
    :class:`StreamConfig`'s fields (``sensor``: a name in sensors/, a .toml file or a Sensor;
    ``profile``: a profile with a receiver, by name or file, or None)

    scenes : the scene catalog (a folder, default: the shipped one, or a loaded Catalog), with
        its scenarios.toml
    batch_size : streams cast together, 1 .. MAX_BATCH / 2 (no effect on the bytes)
    force : replace an existing dataset directory of the same name (else refused)
    progress : a progress bar on stderr; preview : draw ``preview.png``
    workers : processes that simulate batches (the calling one writes them, in order); the
        bytes are the same for every count, as every stream draws from its own random streams
    """
    from tqdm import tqdm

    config = StreamConfig(
        classes=classes, train_size=train_size, test_size=test_size, seed=seed, width=width,
        fov_deg=fov_deg, rotations=rotations, min_object_hits=min_object_hits,
        max_attempts=max_attempts, variation=variation,
        sensor=sensor if isinstance(sensor, Sensor) else load_sensor(sensor), profile=profile,
        fog_visibility_m=fog_visibility_m, rain_rate_mm_h=rain_rate_mm_h,
    )  # fmt: skip
    if isinstance(batch_size, bool) or not isinstance(batch_size, int):
        raise ConfigError(f"batch_size={batch_size!r}: expected an integer in 1..{OBJECT_CELLS}")
    if not 1 <= batch_size <= OBJECT_CELLS:
        raise ConfigError(f"batch_size={batch_size}: expected an integer in 1..{OBJECT_CELLS}")
    catalog = scenes if isinstance(scenes, Catalog) else load_catalog(scenes)
    catalog = catalog.for_sensor(config.sensor.name)
    if catalog.scenarios is None:
        raise ConfigError(
            f"scene catalog {catalog.root} has no scenarios.toml; expected one saying how "
            "objects come into view (docs/streams.md)"
        )
    class_plan(catalog, config.classes)
    # the events of the largest split are held until it is written (at most one a pulse, 24
    # bytes each in memory, the concatenation's copy included)
    largest = max(config.split_sizes.values())
    pulses = config.sensor.beams * config.width * config.rotations
    check_memory(largest * pulses * 24, f"the events of {largest} streams of {pulses} pulses")
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ConfigError(f"workers={workers!r}: expected a number of processes >= 1")
    batches = sum(-(-size // batch_size) for size in config.split_sizes.values())
    workers = capped_workers(workers, batches, "batches")
    name = stream_name(config)
    bar = tqdm(total=train_size + test_size, unit="stream", disable=not progress,
               desc="stream", dynamic_ncols=True)  # fmt: skip
    global _SHARED
    _SHARED = (config, catalog)
    with ExitStack() as stack:
        pool = stack.enter_context(forked_pool(workers)) if workers > 1 else None
        if pool is not None:  # fork now, before any file or lock is open (as generate does)
            pool.submit(int).result()
        try:
            with building(out, name, force) as temp:
                for split in ("test", "train"):
                    write_stream_split(temp / f"{split}.h5", config, catalog, split, batch_size,
                                       bar.update, pool)  # fmt: skip
                bar.close()
                write_release_files(temp, name, preview)
        finally:
            bar.close()
            _SHARED = None
    return Path(out) / name
