"""Scan-timed pulses (`generate --timing scan`): emission times that agree with the firing
geometry, arrival times in the delays, flash twins untouched, events and early decisions in
sensor time."""

import json
from dataclasses import replace
from pathlib import Path

import h5py
import numpy as np
import pytest

from simlidar.data import delay_unit_ns, spike_threshold, to_events
from simlidar.dataset.reader import read_split_info
from simlidar.errors import ConfigError
from simlidar.generator.config import GeneratorConfig
from simlidar.sensor import default_sensor, firing_azimuths_deg, load_sensor, row_order
from simlidar.sensor.rays import emission_times_ns, scan_window_ns

SMALL = ["--train-size", "64", "--test-size", "32", "--profile", "physical"]


@pytest.fixture(scope="module")
def twins(tmp_path_factory, cli):
    """A flash and a scan dataset of the same seed and options."""
    out = tmp_path_factory.mktemp("twins")
    paths = {}
    for timing in ("flash", "scan"):
        result = cli("generate", *SMALL, "--timing", timing, "--out", out, "--json")
        assert result.exit_code == 0, result.output
        paths[timing] = Path(json.loads(result.stdout)["datasets"][0]["path"])
    return paths


def test_a_vlp16_window_fires_laser_by_laser_and_column_by_column():
    sensor = default_sensor()
    t = emission_times_ns(sensor, 16, 36.0, np.array([0.0, 0.37, 0.99]))
    assert t.shape == (3, 16, 16)
    lasers = row_order(sensor)
    # inside a column, laser id j fires j x 2.304 us after the column's cycle starts
    for row, laser in enumerate(lasers):
        assert np.allclose(t[:, row, :] - t[:, lasers.index(0), :], laser * 2304.0)
    assert (t[:, lasers.index(0), 0] == 0.0).all()  # the window's first firing
    starts = t[:, lasers.index(0), :]
    steps = np.diff(starts, axis=1) / 55296.0  # whole cycles between columns, left to right
    assert np.allclose(steps, np.round(steps)) and (steps >= 11).all() and (steps <= 12).all()
    # 36 degrees at 600 RPM: the head needs 10 ms, the columns' centres lie 15/16 of it apart
    assert 9.3e6 < t.max() < 9.5e6


@pytest.mark.parametrize("name", ["vlp16", "hdl64e", "hdl32e"])
def test_emission_times_are_the_firing_azimuths_turned_into_time(name):
    """The clock and the geometry agree: the head turns degrees_per_us, so a pulse's azimuth
    (its rotational correction added back) lies emission x rate past the first firing's."""
    sensor = load_sensor(name)
    phase = np.random.default_rng(1).random(5)
    azimuth = firing_azimuths_deg(sensor, 24, 40.0, phase)
    head = azimuth + np.asarray(sensor.rotations)[row_order(sensor)][None, :, None]
    t = emission_times_ns(sensor, 24, 40.0, phase)
    first = row_order(sensor).index(0)  # laser 0 fires in slot 0
    turned = (head - head[:, first : first + 1, :1]) / sensor.degrees_per_us * 1000.0
    assert np.allclose(turned, t, atol=1e-3)


@pytest.mark.parametrize("width, fov", [(1, 36.0), (16, 36.0), (118, 90.0), (1024, 179.0)])
@pytest.mark.parametrize("name", ["vlp16", "hdl64e"])
def test_every_arrival_lies_inside_the_scan_window(name, width, fov):
    sensor = load_sensor(name)
    phase = np.random.default_rng(2).random(64)
    latest = emission_times_ns(sensor, width, fov, phase).max() + sensor.tof_max_ns
    window = scan_window_ns(sensor, width, fov)
    assert latest < window < latest + 3 * sensor.cycle_us * 1000.0


def test_scan_delays_are_arrival_times_of_the_flash_twin(twins):
    flash, scan = twins["flash"], twins["scan"]
    assert flash.name == "simlidar-32c-noise0.2-physical-v1.0.0"
    assert scan.name == "simlidar-32c-noise0.2-physical-scan-v3.0.0"
    with h5py.File(flash / "train.h5") as f, h5py.File(scan / "train.h5") as g:
        assert set(g) - set(f) == {"emission_ns"} and set(f) <= set(g)
        for name in f:  # same scenes, phases and noise: only the clock differs
            if name not in ("delays", "clean_delays"):
                assert np.array_equal(f[name][:], g[name][:], equal_nan=True), name
        assert g.attrs["timing"] == "scan" and "timing" not in f.attrs
        unit, tof_max = g.attrs["delay_unit_ns"], g.attrs["tof_max_ns"]
        assert unit == scan_window_ns(default_sensor(), 16, 36.0)
        emission = g["emission_ns"][:]
        assert emission.dtype == np.float64
        for name in ("delays", "clean_delays"):
            d_flash, d_scan = f[name][:], g[name][:]
            back = d_flash < 1.0
            assert np.array_equal(d_scan >= 1.0, ~back)  # no return stays 1.0, nothing else is
            arrival = emission + d_flash.astype(np.float64) * tof_max
            # float32 delays of a 10 ms unit: about 0.6 ns apart
            assert np.abs(d_scan[back] * unit - arrival[back]).max() < 1.0
        # the stored emission times are the window's, from the stored phase
        assert np.allclose(
            emission, emission_times_ns(default_sensor(), 16, 36.0, g["phase"][:].astype(float))
        )
    assert delay_unit_ns(read_split_info(scan / "train.h5").attrs) == unit
    assert delay_unit_ns(read_split_info(flash / "train.h5").attrs) == tof_max


def test_a_scan_dataset_says_so_everywhere(twins, cli):
    scan = twins["scan"]
    assert cli("verify", scan).exit_code == 0
    info = cli("info", scan)
    assert "600 RPM, scan timing" in info.stdout and "dataset version 3.0.0" in info.stdout
    card = (scan / "README.md").read_text()
    assert "| timing | `scan`: a delay is the pulse's arrival time" in card
    assert "`emission_ns` | float64 | (N, 16, 16)" in card
    assert "--timing scan" in card
    flash_card = (twins["flash"] / "README.md").read_text()
    assert "| timing | `flash`" in flash_card and "emission_ns" not in flash_card.split("## Gen")[0]


def test_the_card_command_makes_the_scan_dataset_again(twins, tmp_path, cli):
    scan = twins["scan"]
    card = (scan / "README.md").read_text()
    command = card.split("## Regenerate")[1].split("```\n")[1].strip().split()
    again = cli(*command[1:], "--out", tmp_path)
    assert again.exit_code == 0, again.output
    for name in ("train.h5", "test.h5"):
        assert (tmp_path / scan.name / name).read_bytes() == (scan / name).read_bytes()


def test_a_scan_file_without_emission_times_fails_verify(twins, tmp_path, cli):
    import shutil

    copy = tmp_path / twins["scan"].name
    shutil.copytree(twins["scan"], copy)
    with h5py.File(copy / "test.h5", "a") as f:
        del f["emission_ns"]
    result = cli("verify", copy)
    assert result.exit_code != 0 and "dataset 'emission_ns' missing" in result.output


def test_events_of_a_scan_sample_come_in_sweep_order(twins):
    with h5py.File(twins["scan"] / "test.h5") as f:
        sample, emission, attrs = f["delays"][3], f["emission_ns"][3], dict(f.attrs)
    events = to_events(sample, delay_unit_ns(attrs), spike_threshold(attrs))
    assert len(events) == int((sample < 1.0).sum())
    assert (np.diff(events["t"]) >= 0).all() and (events["p"] == 0).all()
    # microseconds (the default tick): each event after its pulse left, within one time of
    # flight at max range (0.67 us), both rounded to the microsecond
    left = emission[events["y"], events["x"]] / 1000.0
    assert (events["t"] >= np.round(left)).all()
    assert (events["t"] <= np.round(left + attrs["tof_max_ns"] / 1000.0)).all()
    assert events["t"].max() > 5000  # a sweep lasts milliseconds
    # the sweep runs left to right: the mean column grows along the event stream
    half = len(events) // 2
    assert events["x"][:half].mean() < events["x"][half:].mean()


def test_early_decisions_are_reported_in_sweep_time(twins):
    from simlidar.bench.early import early_decisions
    from simlidar.bench.train import train
    from simlidar.models.registry import load_recipe

    scan = twins["scan"]
    result = train(load_recipe("snn_simlidar"), scan, epochs=1, progress=False)
    early = early_decisions(result.model, scan, per_sample=True)
    with h5py.File(scan / "test.h5") as f:
        x, unit = f["delays"][:], f.attrs["delay_unit_ns"]
    last = np.where(x < 1.0, x, 0.0).reshape(len(x), -1).max(axis=1) * unit
    assert early["last_input_ns_mean"] == pytest.approx(last.mean())
    times = early["per_sample"]["decision_time_ns"]
    decided = [(t, w) for t, w in zip(times, last) if t is not None]
    assert decided, "an untrained-ish network still decides on some samples"
    # sensor time of a sweep: milliseconds, not the nanoseconds of a time of flight
    assert min(t for t, _ in decided) > 1e4
    assert early["decision_time_ns_mean"] == pytest.approx(np.mean([t for t, _ in decided]))
    assert early["wait_saved_mean"] == pytest.approx(np.mean([1 - t / w for t, w in decided]))
    assert early["clock"] == "sensor" and early["decision_sensor_ns_mean"] == pytest.approx(
        early["decision_time_ns_mean"]
    )


@pytest.mark.parametrize("timing", ["flash", "scan"])
def test_a_far_first_decision_is_on_the_networks_order_and_takes_the_whole_window(twins, timing):
    """Issue 42: far first spikes the far returns first, which a sensor delivers last; its
    decision figures are labelled network order, and in sensor time it has waited for every
    return: the window's end (667 ns after a flash, the sweep's window under scan timing)."""
    from simlidar.bench.early import early_decisions, format_early
    from simlidar.bench.train import train
    from simlidar.dataset.loaders import delay_unit_ns, split_info
    from simlidar.models.registry import load_recipe

    recipe = load_recipe("snn_simlidar")
    recipe["architecture"]["direction"] = "far_first"
    result = train(recipe, twins[timing], epochs=1, progress=False)
    early = early_decisions(result.model, twins[timing])
    window = delay_unit_ns(split_info(twins[timing], "test").attrs)
    assert early["clock"] == "network-order" and early["decision_time_ns_mean"] is None
    assert early["decision_sensor_ns_mean"] == window
    assert window == pytest.approx(667.128, abs=1e-3) if timing == "flash" else window > 9e6
    assert "network order; in sensor time the window's end" in format_early(early)


def test_timing_is_checked_and_stored_only_when_scan():
    config = GeneratorConfig()
    assert "timing" not in config.to_dict() and config.scan_window_ns is None
    scan = replace(config, timing="scan")
    assert scan.to_dict()["timing"] == "scan"
    assert GeneratorConfig.from_dict(scan.to_dict()) == scan
    with pytest.raises(ConfigError, match="timing='sweep'"):
        GeneratorConfig(timing="sweep")


def test_a_bad_timing_is_one_line_and_writes_nothing(tmp_path, cli):
    result = cli("generate", *SMALL, "--timing", "sweep", "--out", tmp_path)
    assert result.exit_code == 2
    assert "'sweep' is not one of 'flash', 'scan'" in result.output
    assert "Traceback" not in result.output and list(tmp_path.iterdir()) == []


def test_a_window_finer_than_the_firing_cycles_is_refused(tmp_path, cli):
    """Columns closer than one firing cycle would share firings (the same pulses twice)."""
    sensor = default_sensor()
    widest = GeneratorConfig(width=180)  # 36 deg / 0.199 deg a cycle at 600 RPM
    t = emission_times_ns(sensor, 180, 36.0, np.random.default_rng(0).random(16))
    assert (np.diff(t[:, 0, :], axis=1) > 0).all()  # every column its own cycle
    assert widest.width == 180
    expected = "width=181: columns 0.1989 deg apart, closer than the 0.1991 deg.*at most 180"
    with pytest.raises(ConfigError, match=expected):
        GeneratorConfig(width=181)
    result = cli("generate", "--width", 200, "--out", tmp_path / "out")
    assert result.exit_code == 2 and "expected at most 180 columns over 36 deg" in result.output
    assert not (tmp_path / "out").exists()


def test_the_bound_reads_a_scan_by_the_sensors_clock(twins):
    """Under the sensor's clock, a scan-timed sample shows the flash twin's times of flight
    once everything has arrived; its spikes arrive in firing order (a time of flight, at most
    667 ns and 133 ns of noise, is shorter than the 2.304 us between two firings)."""
    from simlidar.bench.bound import arrived, sensor_clock, spike_times

    def times(timing):
        info = read_split_info(twins[timing] / "test.h5")
        with h5py.File(info.path) as f:
            return spike_times(f["delays"][:], spike_threshold(info.attrs))

    assert sensor_clock(twins["flash"], "test") is None
    emission, scale = sensor_clock(twins["scan"], "test")
    emission = emission.reshape(len(emission), -1)
    scan, flash = times("scan"), times("flash")
    spiking = np.isfinite(flash)
    assert np.array_equal(np.isfinite(scan), spiking) and spiking.any()
    view, _ = arrived(scan, None, emission, scale)
    # float32 arrival times of a 9.5 ms unit are 0.5 ns apart: 1e-3 of the 667 ns unit
    assert np.abs(view[:, 0][spiking] - flash[spiking]).max() < 2e-3
    first = arrived(scan, 16)[0][:, 1] > 0
    assert (first.sum(axis=1) == 16).all()
    last_in = np.where(first, emission, -np.inf).max(axis=1)
    first_out = np.where(spiking & ~first, emission, np.inf).min(axis=1)
    assert (last_in < first_out).all()


@pytest.mark.parametrize("profile", ["physical", "paper"])
def test_fresh_noise_of_a_scan_split_is_the_flash_twins_made_arrival_times(
    twins, tmp_path, cli, profile
):
    """The networks' and the bound's fresh noise (``noise_augment``) is drawn on the time of
    flight, as the generator draws it, and then made arrival times: the scan draw is the flash
    twin's draw of the same seed on the sweep's clock. Before issue 42 it was added to the
    arrival times, a jitter of the noise level times the whole window (0.2 x 9.5 ms)."""
    from simlidar.bench.augment import fresh_noise
    from simlidar.generator.pulses import scan_delays

    pair = twins
    if profile == "paper":  # a missing return is 0.0 plus noise: it arrives with its emission
        pair = {}
        for timing in ("flash", "scan"):
            args = [*SMALL[:4], "--profile", "paper", "--timing", timing]
            result = cli("generate", *args, "--out", tmp_path, "--json")
            assert result.exit_code == 0, result.output
            pair[timing] = Path(json.loads(result.stdout)["datasets"][0]["path"])
    attrs = {t: read_split_info(pair[t] / "train.h5").attrs for t in pair}
    rows = np.arange(40)
    flash = fresh_noise(pair["flash"], attrs["flash"], seed=5, rows=rows)()
    scan = fresh_noise(pair["scan"], attrs["scan"], seed=5, rows=rows)()
    with h5py.File(pair["scan"] / "train.h5") as g:
        emission = g["emission_ns"][:40]
    a = attrs["scan"]
    expected = scan_delays(flash, emission, a["tof_max_ns"], a["delay_unit_ns"])
    assert np.array_equal(scan >= 1.0, expected >= 1.0)
    # float32 arrival times of a 9.5 ms unit are 0.5 ns apart; the noise is 0.2 x 667 ns
    assert np.abs(scan - expected).max() * a["delay_unit_ns"] < 2.0
    stored = load_split_field(pair["scan"], "delays")[:40]
    both = (stored < 1.0) & (scan < 1.0)  # (noise can push a return past the window: 1.0)
    jitter = np.abs(scan - stored)[both] * a["delay_unit_ns"]
    assert both.mean() > 0.5 and jitter.max() < 0.2 * a["tof_max_ns"] + 2.0


def load_split_field(path: Path, field: str) -> np.ndarray:
    with h5py.File(path / "train.h5") as f:
        return f[field][:]
