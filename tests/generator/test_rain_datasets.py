"""Rain in generated datasets (issue 41, item 4): a new dataset version whose drops make near
returns of surface 0 and whose extinction only takes returns away from the clear-air twin, the
same bytes whatever the batches and workers, a card that says so, and one-line errors."""

import numpy as np
import pytest

from simlidar.sensor.weather import rain

C_M_PER_NS = 0.299792458


@pytest.fixture(scope="module")
def made(tmp_path_factory, sensor_dataset):
    out = tmp_path_factory.mktemp("rain")
    return {
        "clear": sensor_dataset(out / "a"),
        "rain": sensor_dataset(out / "b", rain_rate_mm_h=200.0),
    }


def test_rain_is_a_dataset_version_of_its_own(made, read_split):
    assert made["clear"].name == "simlidar-32c-noise0.1-sensor-v5.0.0"
    assert made["rain"].name == "simlidar-32c-noise0.1-sensor-rain200.0-v5.0.0"
    _, attrs = read_split(made["rain"])
    assert '"rain_rate_mm_h": 200.0' in attrs["config"] and attrs["dataset_version"] == "5.0.0"
    _, clear = read_split(made["clear"])
    assert "rain_rate_mm_h" not in clear["config"]


def test_the_drops_make_near_returns_and_the_extinction_takes_far_ones(made, read_split):
    """The drops echo as LISA's (water's Fresnel reflectance times their share of the beam):
    at 200 mm/h some pulses return a drop (surface 0), each beyond the receiver's r_1 and no
    farther than a drop 8 mm wide could be seen (a surface-0 return farther is a false alarm,
    rare), with the reflectivity byte of its measured
    signal; beyond any drop, the extinction takes far surfaces."""
    from simlidar.sensor.receiver import (
        apparent_reflectance,
        crossover_ranges,
        load_receiver,
        reflectivity_byte,
    )

    rainy, _ = read_split(made["rain"])
    clear, _ = read_split(made["clear"])
    np.testing.assert_array_equal(rainy["labels"], clear["labels"])  # the same scenes
    surface = rainy["returns_surface"][..., 0]
    range_m = rainy["returns_tof_ns"][..., 0] * C_M_PER_NS / 2
    drop = surface == 0
    drop &= ~np.isnan(range_m)
    assert drop.sum() > 10
    receiver = load_receiver("vlp16")
    geometry = crossover_ranges(receiver)
    drops = rain(80.0, 3.1416e-4, 0.05, receiver.threshold_w, 3.0, 1.5, 200.0, geometry)
    assert range_m[drop].min() > geometry[0] - 0.4  # noise: the edge's jitter
    beyond = range_m[drop] >= drops.reach_m * np.sqrt(8.0)  # the noise's false alarms
    assert beyond.sum() < 1e-3 * drop.size and (~beyond).sum() > 10
    own = (rainy["surface"] == 0) & ~np.isnan(rainy["tof_ns"])
    tof_m = rainy["tof_ns"][own].astype(np.float64) * C_M_PER_NS / 2
    apparent = apparent_reflectance(receiver, rainy["power_w"][own].astype(np.float64), tof_m)
    byte = reflectivity_byte(receiver, apparent, apparent > 1.0).astype(int)
    # the stored range carries the return's noise (a few cm at a few metres): a few per cent
    assert (np.abs(rainy["intensity"][own].astype(int) - byte) <= 2 + 0.05 * byte).all()
    # beyond any drop, fewer far surfaces return than in clear air (the extinction's losses)
    far = clear["tof_ns"] * C_M_PER_NS / 2 > 20.0
    hard_rain = (rainy["surface"] > 0) & far
    assert hard_rain.sum() < ((clear["surface"] > 0) & far).sum()


def test_the_same_seed_gives_the_same_bytes_whatever_the_batches_and_workers(
    made, tmp_path, sensor_dataset, dataset_digest
):
    again = sensor_dataset(tmp_path / "a", rain_rate_mm_h=200.0, batch_size=5)
    pool = sensor_dataset(tmp_path / "b", rain_rate_mm_h=200.0, workers=2)
    assert dataset_digest(again) == dataset_digest(pool) == dataset_digest(made["rain"])


def test_the_card_says_rain_and_lists_the_notes_up_to_its_version(made, cli):
    card = (made["rain"] / "README.md").read_text()
    assert "--profile sensor" in card and "--rain 200.0" in card
    assert "rain of 200 mm/h" in card and "Marshall-Palmer" in card
    assert "* 4.2.0 (2026-11-26): Rain" in card and "* 5.0.0 (2026-11-28): A receiver" in card
    clear = (made["clear"] / "README.md").read_text()
    assert "* 5.0.0 (2026-11-28): A receiver calibrated to measurement" in clear
    assert cli("verify", made["rain"]).exit_code == 0


@pytest.mark.parametrize(
    "options, expected",
    [
        (("--profile", "physical", "--rain", "10"), "expected a profile with a receiver"),
        (("--profile", "sensor", "--rain", "-1"), "not in the range 0<=x<=500"),
        (("--profile", "sensor", "--rain", "1000"), "not in the range 0<=x<=500"),
        (("--profile", "sensor", "--rain", "nan"), "'nan' is not a number in the range 0<=x<=500"),
    ],
)
def test_a_wrong_rain_is_one_line_and_writes_nothing(tmp_path, cli, refused, options, expected):
    refused(cli("generate", *options, "--out", tmp_path / "o"), tmp_path / "o", expected)
