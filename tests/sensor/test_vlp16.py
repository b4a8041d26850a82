import math

import numpy as np
import pytest

from simlidar.errors import ConfigError
from simlidar.sensor import VLP16, row_order, tof_ns

# VLP-16 user manual 63-9243 Rev D, laser ids 0..15 in firing order.
MANUAL_ELEVATIONS = [-15, 1, -13, 3, -11, 5, -9, 7, -7, 9, -5, 11, -3, 13, -1, 15]
MANUAL_OFFSETS_MM = [11.2, -0.7, 9.7, -2.2, 8.1, -3.7, 6.6, -5.1,
                     5.1, -6.6, 3.7, -8.1, 2.2, -9.7, 0.7, -11.2]  # fmt: skip


def test_beam_table_equals_the_manual():
    sensor = VLP16()
    assert list(sensor.elevations_deg) == MANUAL_ELEVATIONS
    assert list(sensor.vertical_offsets_mm) == MANUAL_OFFSETS_MM


def test_timing_and_rates_follow_the_manual():
    sensor = VLP16(rpm=600)
    assert sensor.firing_interval_us == 2.304
    assert sensor.cycle_us == pytest.approx(16 * 2.304 + 18.432)
    # 600 RPM = 3600 deg/s; one 55.296 us cycle -> 0.1990656 deg.
    assert sensor.azimuth_step_deg == pytest.approx(3600 * 55.296e-6)
    assert VLP16(rpm=300).azimuth_step_deg == pytest.approx(0.0995328)
    assert VLP16(rpm=1200).azimuth_step_deg == pytest.approx(0.3981312)
    assert sensor.points_per_second == pytest.approx(289_352, rel=1e-4)  # manual: ~289,344
    assert sensor.range_resolution_m == 0.002


def test_time_of_flight_by_hand():
    # 2 x 10 m / 299,792,458 m/s = 66.7128 ns
    assert tof_ns(10.0) == pytest.approx(66.71, abs=0.005)
    assert VLP16().tof_max_ns == pytest.approx(2 * 100 / 299_792_458 * 1e9)


def test_rows_run_from_the_highest_elevation_down():
    sensor = VLP16()
    elevations = [sensor.elevations_deg[k] for k in row_order(sensor)]
    assert elevations == sorted(MANUAL_ELEVATIONS, reverse=True)


@pytest.mark.parametrize(
    "kwargs, word",
    [
        ({"rpm": 1500.0}, "rpm=1500.0"),
        ({"rpm": 200.0}, "rpm=200.0"),
        ({"rpm": 610.0}, "rpm=610.0: expected 300 to 1200 in steps of 60"),
        ({"min_range_m": 5.0, "max_range_m": 2.0}, "range limits"),
        ({"mount_height_m": 0.0}, "mount_height_m=0.0"),
        ({"pitch_deg": 45.0}, "pitch_deg=45.0"),
        ({"elevations_deg": (0.0,) * 15}, "16 elevations"),
    ],
)
def test_bad_sensor_values_are_named(kwargs, word):
    with pytest.raises(ConfigError, match=word.replace(".", r"\.")):
        VLP16(**kwargs)


def test_config_round_trips_through_json_form():
    sensor = VLP16(rpm=900.0, mount_height_m=2.1, pitch_deg=1.5)
    assert VLP16.from_dict(sensor.to_dict()) == sensor
    assert math.isclose(sensor.to_dict()["rpm"], 900.0)
    assert np.isfinite(list(sensor.to_dict()["elevations_deg"])).all()
