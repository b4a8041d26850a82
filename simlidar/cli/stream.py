"""``simlidar stream``: pulse-stream datasets of moving scenes (docs/streams.md)."""

import json
import time

import click

from simlidar.cli.generate import (
    catalog_for,
    chosen_sensor_of,
    out_option,
    receiver_options,
    sensor_option,
)
from simlidar.cli.options import batch_options, scenes_option, setting_option
from simlidar.generator.stream_config import StreamConfig
from simlidar.generator.stream_files import BATCH, generate_streams
from simlidar.sensor.moving import OBJECT_CELLS


@click.command()
@setting_option(StreamConfig, "classes")
@setting_option(StreamConfig, "rotations")
@setting_option(StreamConfig, "train_size")
@setting_option(StreamConfig, "test_size")
@setting_option(StreamConfig, "seed")
@setting_option(StreamConfig, "width")
@setting_option(StreamConfig, "variation")
@sensor_option
@receiver_options(
    "A profile with a receiver (sensor, or a .toml file): a hit is an event only when the "
    "receiver detects it, with its range noise, reflectivity byte and false alarms "
    "(docs/streams.md). [default: none: every hit in range is an event]"
)
@scenes_option
@batch_options(OBJECT_CELLS, BATCH, "Streams")
@out_option("the dataset directory")
@click.option("--force", is_flag=True, help="Overwrite an existing dataset directory.")
@click.option("--no-preview", is_flag=True, help="Do not draw preview.png.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object on stdout.")
def stream(classes, rotations, train_size, test_size, seed, width, variation, sensor, profile,
           fog_visibility_m, rain_rate_mm_h, scenes, batch_size, workers, out, force, no_preview,
           as_json):  # fmt: skip
    """Generate a pulse-stream dataset of moving scenes: several rotations of the sensor's
    window while the ego drives and an object comes into view (oncoming, overtaking,
    crossing), every pulse cast at its own time, as ragged events and dense times of flight,
    with the time each object first returns (docs/streams.md). With --profile sensor, through
    the VLP-16's receiver, in fog (--fog) or rain (--rain) if asked."""
    start = time.perf_counter()
    path = generate_streams(
        out, classes=classes, train_size=train_size, test_size=test_size, seed=seed,
        width=width, rotations=rotations, variation=variation, sensor=chosen_sensor_of(sensor),
        profile=profile, fog_visibility_m=fog_visibility_m, rain_rate_mm_h=rain_rate_mm_h,
        scenes=catalog_for(scenes, classes), batch_size=batch_size, force=force,
        progress=not as_json, preview=not no_preview, workers=workers,
    )  # fmt: skip
    seconds = time.perf_counter() - start
    if as_json:
        record = {"path": str(path), "train": train_size, "test": test_size}
        click.echo(json.dumps(record | {"seconds": round(seconds, 3)}))
        return
    click.echo(f"wrote {path} ({train_size} + {test_size} streams of {rotations} rotations)")
    click.echo(f"done in {seconds:.1f} s")
