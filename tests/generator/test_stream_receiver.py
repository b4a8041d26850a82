"""Pulse streams through the calibrated receiver (simlidar stream --profile sensor [--fog V |
--rain R], stream dataset version 1.1.0): the same scenes as without one, events that are
detected hits (or the weather's and the noise's, surface 0), the time an object first returns
counted from its detected events, the new fields written, read and checked, and the refusals."""

import shutil

import h5py
import numpy as np
import pytest

from simlidar.dataset.stream_loaders import StreamEventDataset, load_stream
from simlidar.errors import ConfigError
from simlidar.generator.pulse_streams import simulate_streams
from simlidar.generator.stream_config import StreamConfig
from simlidar.generator.stream_files import generate_streams, stream_name
from simlidar.release.verify import verify

PLAIN = StreamConfig(classes=4, train_size=8, test_size=4)
SENSOR = StreamConfig(classes=4, train_size=8, test_size=4, profile="sensor")
FOG = StreamConfig(classes=4, train_size=8, test_size=4, profile="sensor", fog_visibility_m=30.0)


@pytest.fixture(scope="module")
def batches(catalog):
    return {
        name: simulate_streams(config, catalog, "train", 0, 16)
        for name, config in (("plain", PLAIN), ("sensor", SENSOR), ("fog", FOG))
    }


@pytest.fixture(scope="module")
def written(tmp_path_factory, catalog):
    out = tmp_path_factory.mktemp("receiver-streams")
    return generate_streams(out, train_size=8, test_size=4, profile="sensor", rain_rate_mm_h=50.0,
                            progress=False, preview=False, scenes=catalog)  # fmt: skip


def _by_sample(batch, name):
    return np.split(getattr(batch, name), np.cumsum(batch.event_count)[:-1])


def test_the_receiver_sees_the_same_scenes(batches):
    """A stream's scene, scenario, motion and draws are decided before the receiver: the same
    with and without one, in clear air and in fog; the object's first hit in range is the
    first event on it where every hit returns."""
    plain = batches["plain"]
    for name in ("sensor", "fog"):
        other = batches[name]
        for field in ("labels", "scenario", "phase", "attempts", "object_motion", "ego_motion"):
            assert np.array_equal(getattr(other, field), getattr(plain, field)), (name, field)
        assert np.array_equal(other.object_track, plain.object_track, equal_nan=True)
        assert np.array_equal(other.t_in_view_us, plain.t_visible_us, equal_nan=True)
    assert plain.t_in_view_us is None and plain.event_intensity is None


def test_visible_time_is_the_first_detected_event_on_the_object(batches):
    """t_visible_us is the arrival of the first event on the object (every stream), never
    before the object's first hit; where the receiver detected none of its hits it is NaN and
    the latencies count from t_in_view_us."""
    for name in ("sensor", "fog"):
        batch = batches[name]
        times, on = _by_sample(batch, "event_t_us"), _by_sample(batch, "event_object")
        surface = _by_sample(batch, "event_surface")
        for i in range(len(batch.labels)):
            assert (np.diff(times[i]) >= 0).all()
            assert not (on[i] & (surface[i] == 0)).any()  # the weather's echo, the noise's
            if not on[i].any():
                assert np.isnan(batch.t_visible_us[i])
                if batch.object[i] != 0:
                    assert batch.t_reference_us[i] == batch.t_in_view_us[i]
                continue
            assert batch.t_visible_us[i] == times[i][on[i]].min()
            assert batch.t_reference_us[i] == batch.t_visible_us[i]
            # the first detection comes with or after the first hit (range noise: 1 us = 150 m)
            assert batch.t_visible_us[i] >= batch.t_in_view_us[i] - 1.0
            assert batch.object_events[i] == on[i].sum()


def test_events_are_detected_hits_or_the_noise(batches):
    """In clear air an event of a surface is a hit the receiver detected: the pulse hit that
    surface where every hit returns, at about its range (the noise's few cm); the receiver
    drops some hits and adds few false alarms (surface 0)."""
    plain, sensor = batches["plain"], batches["sensor"]
    key = {}
    for b, batch in (("plain", plain), ("sensor", sensor)):
        sample = np.repeat(np.arange(len(batch.labels)), batch.event_count)
        key[b] = (sample, batch.event_rotation, batch.event_y, batch.event_x)
    pulses = {k: i for i, k in enumerate(zip(*key["plain"]))}
    alarms, matched = 0, 0
    for j, k in enumerate(zip(*key["sensor"])):
        if sensor.event_surface[j] == 0:
            alarms += 1
            continue
        i = pulses[k]  # a detected hit is a hit
        assert sensor.event_surface[j] == plain.event_surface[i]
        assert abs(float(sensor.event_range_m[j]) - float(plain.event_range_m[i])) < 1.0
        matched += 1
    assert matched < len(plain.event_t_us)  # the receiver drops some hits (the far road)
    pulses = len(sensor.labels) * 16 * 320
    assert alarms <= 1e-3 * pulses  # T is set for a false alarm in 1e-4 of pulses
    assert (sensor.event_intensity[sensor.event_surface != 0] > 0).mean() > 0.9


def test_thick_fog_clutters_and_hides(batches):
    """At 30 m visibility the fog's own echoes (surface 0) are most events, and the objects
    return less than in clear air."""
    fog, sensor = batches["fog"], batches["sensor"]
    assert (fog.event_surface == 0).mean() > 0.5
    assert fog.object_events.sum() < sensor.object_events.sum()


def test_written_dataset_reads_and_verifies(written, tmp_path, catalog):
    """Version 1.1.0 by name and attribute, the receiver's attributes and the new fields
    written, read by load_stream and StreamEventDataset, accepted by verify; the same bytes
    for two workers."""
    assert written.name == "simlidar-stream-4c-10rot-w32-sensor-rain50.0-v1.1.0"
    assert verify(written) == []
    with h5py.File(written / "train.h5") as f:
        assert f.attrs["dataset_version"] == "1.1.0"
        assert {"receiver", "receiver_sha256", "materials", "materials_sha256"} <= set(f.attrs)
        assert f["event_intensity"].shape == f["event_t_us"].shape
    split = load_stream(written, "train")
    assert split.events.intensity is not None and "t_in_view_us" in split.samples
    events, _ = StreamEventDataset(written, fields=("intensity",))[0]
    assert events.dtype.names == ("x", "y", "t", "p", "intensity")
    again = generate_streams(tmp_path, train_size=8, test_size=4, profile="sensor",
                             rain_rate_mm_h=50.0, progress=False, preview=False, scenes=catalog,
                             batch_size=3, workers=2)  # fmt: skip
    for name in ("train.h5", "test.h5", "README.md"):
        assert (again / name).read_bytes() == (written / name).read_bytes()


def test_a_receiver_stream_without_its_intensity_is_refused(written, tmp_path):
    copy = tmp_path / written.name
    shutil.copytree(written, copy)
    with h5py.File(copy / "train.h5", "a") as f:
        del f["event_intensity"]
    assert any("dataset 'event_intensity' missing" in p for p in verify(copy))


def test_intensity_of_a_stream_without_a_receiver_is_refused(tmp_path, catalog):
    plain = generate_streams(tmp_path, train_size=4, test_size=4, progress=False, preview=False,
                             scenes=catalog)  # fmt: skip
    assert plain.name.endswith("-v1.0.0")  # without a receiver: 1.0.0's records and version
    with pytest.raises(ConfigError, match="has no intensity .a stream without a receiver"):
        StreamEventDataset(plain, fields=("intensity",))


def test_the_name_says_the_weather():
    assert stream_name(FOG) == "simlidar-stream-4c-10rot-w32-sensor-fog30.0-v1.1.0"


@pytest.mark.parametrize(
    "args, match",
    [
        (("--fog", "50"), "fog_visibility_m=50.0 (--fog): expected a profile with a receiver"),
        (("--profile", "paper"), "profile='paper' (--profile): expected a profile with a receiver"),
        (("--profile", "nonesuch"), "nonesuch"),
        (("--profile", "sensor", "--rain", "-1"), "--rain"),
    ],
)
def test_cli_refuses_in_one_line(cli, tmp_path, args, match):
    result = cli("stream", "--out", tmp_path / "out", "--test-size", 4, "--train-size", 4, *args)
    assert result.exit_code != 0
    assert match in result.output and "Traceback" not in result.output
    assert len(result.output.strip().splitlines()) == 1, result.output
    assert not (tmp_path / "out").exists()


def test_a_receiver_stream_without_its_materials_is_refused(written, tmp_path):
    copy = tmp_path / written.name
    shutil.copytree(written, copy)
    with h5py.File(copy / "test.h5", "a") as f:
        del f.attrs["materials"]
    assert any("attribute 'materials' missing" in p for p in verify(copy))
