"""What bounds a sweep's frame and the frames simulated together (issue 58, finding 2).

Attack list: a sensor file whose rotation is slow enough (its own rpm_min and rpm) or whose
firing cycle is short enough to make one frame gigabytes: it was a MemoryError (0.1 RPM), an
HDF5 "chunk size > 4GB" error (0.001 RPM) or an object-dtype error (1e-300 RPM), each a
traceback; a beam footprint of 169 sub-rays a pulse, cast for 16 frames at once (13.7 GB for
the VLP-16).
"""

import json
import math
from dataclasses import asdict

import pytest

import simlidar.resources
from simlidar.dataset.schema import sweep_schema
from simlidar.dataset.storage import MAX_CHUNK_BYTES
from simlidar.errors import ResourceError
from simlidar.generator import sweep as sweep_module
from simlidar.generator.config import GeneratorConfig
from simlidar.generator.profiles import load_profile
from simlidar.generator.sweep import (
    FRAME_BATCH,
    MAX_BATCH_BYTES,
    SweepConfig,
    frame_bytes,
    frames_a_batch,
    sweep,
)
from simlidar.sensor import default_sensor, load_sensor, sensor_names
from simlidar.sensor.rays import MAX_ROTATION_PULSES


def _sensor_file(tmp_path, name="slow", **changes):
    """A sensor file of the VLP-16's values with ``changes``; JSON writes the TOML values."""
    values = {k: v for k, v in asdict(default_sensor()).items() if k != "name" and v != ()}
    path = tmp_path / f"{name}.toml"
    path.write_text("".join(f"{k} = {json.dumps(v)}\n" for k, v in (values | changes).items()))
    return path


SLOW = [
    # 1.7e10 pulses a frame: HDF5 refused a chunk of over 4 GB
    ({"rpm_min": 0.001, "rpm": 0.001}, "rpm=0.001, cycle_us=55.296: a rotation of 16 beams"),
    # 1.7e8 pulses: a MemoryError
    ({"rpm_min": 0.1, "rpm": 0.1}, "rpm=0.1, cycle_us=55.296: a rotation of 16 beams"),
    # 1.7e307 pulses: numpy made the shapes of objects, which HDF5 has no type for
    ({"rpm_min": 1e-300, "rpm": 1e-300}, "rpm=1e-300, cycle_us=55.296: a rotation"),
    # a short cycle does the same at the factory speed
    ({"firing_interval_us": 1e-7, "cycle_us": 1e-5}, "rpm=600.0, cycle_us=1e-05: a rotation"),
]


@pytest.mark.parametrize("changes, message", SLOW)
def test_a_frame_of_too_many_pulses_is_one_line_naming_the_keys(tmp_path, cli, changes, message):
    path = _sensor_file(tmp_path, **changes)
    out = tmp_path / "out"
    result = cli("sweep", "--sensor", path, "--frames", 1, "--out", out)
    assert result.exit_code == 2, result.output
    (line,) = result.output.strip().splitlines()
    assert line.startswith(f"Error: sensor slow: {message}") and "Traceback" not in line
    assert line.endswith(
        f"expected at most {MAX_ROTATION_PULSES} pulses a rotation (a sweep's frame): a higher "
        "rpm or a longer cycle_us"
    )
    assert not out.exists()


def test_the_slow_rotation_is_refused_in_a_process_with_little_memory(tmp_path, limited_python):
    """The refusal comes before anything is allocated: a real process under a 3 GiB
    address-space limit (the 0.1 RPM frame was a MemoryError traceback)."""
    path = _sensor_file(tmp_path, rpm_min=0.1, rpm=0.1)
    out = tmp_path / "out"
    args = ["-m", "simlidar.cli", "sweep", "--sensor", path, "--frames", 1, "--out", out]
    result = limited_python(args, 3 * 2**30, timeout=120)
    assert result.returncode == 2, result.stderr
    (line,) = result.stderr.strip().splitlines()
    assert line.startswith("Error: sensor slow: rpm=0.1, cycle_us=55.296: a rotation of 16")
    assert not out.exists()


@pytest.mark.parametrize("name", sensor_names())
def test_every_shipped_sensor_sweeps_its_frames_sixteen_at_a_time(name):
    """Ordinary sweeps batch as before: 16 frames of the largest (the HDL-64E) take about a
    third of MAX_BATCH_BYTES."""
    config = GeneratorConfig(sensor=load_sensor(name))
    assert frames_a_batch(config) == FRAME_BATCH
    assert 2 * FRAME_BATCH * frame_bytes(config) < MAX_BATCH_BYTES


def test_a_frame_at_the_bound_fits_a_chunk_a_reader_reads():
    """Every stored array of a frame (one chunk a frame), and the rotation's emission times
    (H, C) float64, at MAX_ROTATION_PULSES pulses and 2 returns a pulse (dual mode)."""
    h, c = 128, MAX_ROTATION_PULSES // 128
    for dtype, tail in sweep_schema(2).values():
        assert math.prod(tail(h, c)) * len(bytes(dtype, "ascii")) <= MAX_CHUNK_BYTES
    assert MAX_ROTATION_PULSES * 8 * 8 <= MAX_CHUNK_BYTES  # with room to spare


def test_frames_with_many_rays_are_simulated_fewer_at_a_time():
    """By their memory (frame_bytes): a VLP-16 frame through fog takes about 79 MB, with a
    footprint of 169 sub-rays a pulse 856 MB (measured: 3 such frames 1.03 GB peak, 2.61 GB
    when cast together)."""
    sensor = load_profile("sensor")
    fog = GeneratorConfig.from_profile(sensor, fog_visibility_m=50.0)
    assert frames_a_batch(fog) == 13
    footprint = GeneratorConfig.from_profile(sensor, beam_samples=8)
    assert frames_a_batch(footprint) == 1 and frames_a_batch(footprint, 4) == 1
    assert frames_a_batch(GeneratorConfig(), 5) == 5


def test_frames_simulated_one_at_a_time_have_the_same_bytes(tmp_path, catalog, monkeypatch):
    config, frames = GeneratorConfig(), SweepConfig(frames=3)
    whole = sweep(config, frames, catalog, tmp_path / "a", progress=False)
    monkeypatch.setattr(sweep_module, "MAX_BATCH_BYTES", 1)
    assert frames_a_batch(config) == 1
    single = sweep(config, frames, catalog, tmp_path / "b", progress=False)
    assert (single / "frames.h5").read_bytes() == (whole / "frames.h5").read_bytes()


def test_a_frame_the_machine_cannot_hold_is_refused_before_anything_is_written(
    tmp_path, catalog, monkeypatch, cli
):
    """One VLP-16 frame of 169 sub-rays a pulse takes about 0.8 GiB; with 100 MiB to spare the
    sweep stops before it starts (a ResourceError, exit 1), in one line."""
    monkeypatch.setattr(simlidar.resources, "available_memory", lambda: 100 * 2**20)
    config = GeneratorConfig.from_profile(load_profile("sensor"), beam_samples=8)
    with pytest.raises(ResourceError) as caught:
        sweep(config, SweepConfig(frames=2), catalog, tmp_path / "out", progress=False)
    assert str(caught.value) == (
        "sweep of sensor vlp16: 1 frame(s) of 16 x 1808 pulses, 169 ray(s) a pulse: 816.6 MiB "
        "to hold in memory, 100.0 MiB available; expected data that fits (a smaller split, or "
        "a machine with more memory)"
    )
    options = ["--profile", "sensor", "--beam-samples", 8, "--frames", 2]
    result = cli("sweep", *options, "--out", tmp_path / "out")
    assert result.exit_code == 1 and result.output.startswith("Error: sweep of sensor vlp16")
    assert len(result.output.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()


def test_a_sensor_at_the_edge_of_the_ray_casters_cell_sweeps(tmp_path, catalog):
    """The sensor file's bound is the ray caster's: max_range_m + mount_height_m + the largest
    vertical offset just under 169 m is read and cast (167.1 + 1.8 + 0.0112 m)."""
    sensor = load_sensor(_sensor_file(tmp_path, "far", max_range_m=167.1))
    path = sweep(GeneratorConfig(sensor=sensor), SweepConfig(frames=1), catalog, tmp_path,
                 progress=False)  # fmt: skip
    assert (path / "frames.h5").is_file()
