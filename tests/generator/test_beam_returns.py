"""Beam footprints and return modes in generated datasets (issue 41): one ray a pulse through
the waveform gives the single ray's records exactly, a footprint keeps the scenes and adds echoes,
the dual mode stores the manual's two returns, the same seed gives the same bytes whatever the
batches and workers, and a wrong option is one line."""

import dataclasses

import h5py
import numpy as np
import pytest

from simlidar.errors import ConfigError
from simlidar.generator.profiles import load_profile
from simlidar.generator.returns import check_physics, receiver_physics
from simlidar.sensor.model import load_sensor

PIXELS = ("delays", "clean_delays", "tof_ns", "surface", "intensity", "reflectance", "power_w")
SCENE = ("labels", "layout", "object", "object_pose", "object_hits", "attempts", "phase")


@pytest.fixture(scope="module")
def made(tmp_path_factory, sensor_dataset):
    out = tmp_path_factory.mktemp("beams")
    return {
        "one ray": sensor_dataset(out / "a"),
        "one ray, dual": sensor_dataset(out / "b", return_mode="dual"),
        "one ray, last": sensor_dataset(out / "c", return_mode="last"),
        "footprint, dual": sensor_dataset(out / "d", beam_samples=2, return_mode="dual"),
    }


def test_one_ray_through_the_waveform_gives_the_single_rays_records(made, read_split):
    """A lone Gaussian's fitted peak is the ray's own time and power, and both paths draw the
    same noise in the same order (the measurement, the false alarms, then the range noise), so
    every per-pixel field of the last and dual modes is the single ray's, bit for bit, but
    where the noise raised a false alarm (a second echo the modes may report otherwise)."""
    base, attrs = read_split(made["one ray"])
    assert made["one ray"].name == "simlidar-32c-noise0.1-sensor-v5.0.0"
    assert "return_mode" not in attrs and "echoes" not in base
    for name in ("one ray, dual", "one ray, last"):
        data, attrs = read_split(made[name])
        assert made[name].name.endswith(f"-sensor-{attrs['return_mode']}-v5.0.0")
        alarm = (data["echoes"] >= 2) | ((data["surface"] == 0) & ~np.isnan(data["tof_ns"]))
        assert alarm.mean() < 1e-3
        for field in PIXELS + SCENE:
            ours, theirs = data[field], base[field]
            if ours.shape == alarm.shape:
                ours, theirs = ours[~alarm], theirs[~alarm]
            assert np.array_equal(ours, theirs, equal_nan=True), (name, field)
        assert set(np.unique(data["echoes"][~alarm])) <= {0, 1}  # one ray: one echo
        assert np.array_equal((data["echoes"] == 1)[~alarm], ~np.isnan(base["tof_ns"])[~alarm])
    dual, _ = read_split(made["one ray, dual"])
    assert dual["returns_tof_ns"].shape == base["tof_ns"].shape + (2,)
    one = dual["echoes"] <= 1
    for field in ("returns_tof_ns", "returns_intensity", "returns_surface"):
        # one echo is reported twice (the manual: the block pairs are then identical)
        pair = dual[field][one]
        assert np.array_equal(pair[..., 0], pair[..., 1], equal_nan=True)
    got = dual["returns_tof_ns"][..., 0][one]
    assert np.array_equal(got, base["tof_ns"][one], equal_nan=True)


def test_a_footprint_keeps_the_scenes_and_reports_the_first_return(made, read_split):
    """The scene is judged by each beam's axis, as with one ray, so the samples are the same;
    the per-pixel fields hold the first of the reported returns."""
    base, _ = read_split(made["one ray"])
    data, attrs = read_split(made["footprint, dual"])
    assert attrs["beam_samples"] == 2 and attrs["return_mode"] == "dual"
    assert made["footprint, dual"].name == "simlidar-32c-noise0.1-sensor-beam2-dual-v5.0.0"
    for field in SCENE:
        assert np.array_equal(data[field], base[field], equal_nan=True), field
    returns = data["returns_tof_ns"]
    seen = ~np.isnan(returns).all(axis=-1)
    assert np.array_equal(seen, ~np.isnan(data["tof_ns"]))
    assert np.array_equal(data["tof_ns"][seen], np.nanmin(returns[seen], axis=-1))
    assert (data["echoes"][seen] >= 1).all()
    two = data["echoes"] >= 2  # a beam across an edge: two distinct returns where two echoes
    assert two.any()
    assert (returns[two][:, 0] != returns[two][:, 1]).all()
    assert (returns[two][:, 0] > returns[two][:, 1]).all()  # the last first, as the manual
    # a weak return near the sensor can read 0 (under 0.5 % apparent), as KITTI's do
    assert (data["returns_intensity"][~np.isnan(returns)] > 0).mean() > 0.95
    same = ~np.isnan(data["tof_ns"]) & ~two
    agree = np.isclose(data["tof_ns"][same], base["tof_ns"][same], atol=1.0)  # within 15 cm
    assert agree.mean() > 0.95


def test_the_same_seed_gives_the_same_bytes_whatever_the_batches_and_workers(
    made, tmp_path, sensor_dataset, dataset_digest
):
    again = sensor_dataset(tmp_path / "a", beam_samples=2, return_mode="dual", batch_size=5)
    pool = sensor_dataset(tmp_path / "b", beam_samples=2, return_mode="dual", workers=2)
    assert dataset_digest(again) == dataset_digest(pool) == dataset_digest(made["footprint, dual"])


def test_the_card_and_verify_know_the_returns(made, tmp_path, cli, copy_dataset):
    path = made["footprint, dual"]
    card = (path / "README.md").read_text()
    assert "--profile sensor" in card and "--beam-samples 2 --return-mode dual" in card
    assert "7 sub-ray(s) in 2 ring(s)" in card and "`returns_tof_ns` | float32" in card
    assert cli("verify", path).exit_code == 0
    copy = copy_dataset(path, tmp_path / "d")
    with h5py.File(copy / "test.h5", "a") as f:
        del f["returns_tof_ns"]
    result = cli("verify", copy)
    assert result.exit_code == 1 and "dataset 'returns_tof_ns' missing" in result.output


@pytest.mark.parametrize("option", [("--beam-samples", "3"), ("--return-mode", "dual")])
def test_returns_without_a_receiver_are_one_line_and_write_nothing(tmp_path, cli, refused, option):
    result = cli("generate", "--profile", "physical", *option, "--out", tmp_path / "o")
    refused(result, tmp_path / "o", "expected a profile with a receiver")


def test_a_mode_the_receiver_lacks_is_refused(catalog):
    physics = receiver_physics(load_profile("sensor"))
    strongest_only = dataclasses.replace(physics.receiver, return_modes=("strongest",))
    physics = dataclasses.replace(physics, receiver=strongest_only)
    with pytest.raises(ConfigError, match=r"return_mode='dual' \(--return-mode\): receiver"):
        check_physics(physics, load_sensor("vlp16"), catalog.surfaces, "dual")
