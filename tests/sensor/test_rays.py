from dataclasses import replace

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from simlidar.sensor import (
    column_centres_deg,
    default_sensor,
    firing_azimuths_deg,
    row_order,
    window_rays,
)


@settings(max_examples=30, deadline=None)
@given(
    rpm=st.integers(5, 20).map(lambda k: 60.0 * k),  # the manual's settings
    pitch=st.floats(-10, 10),
    width=st.integers(1, 64),
    fov=st.floats(1.0, 170.0),
    phase=st.floats(0.0, 0.999),
)
def test_ray_directions_are_unit_vectors(rpm, pitch, width, fov, phase):
    sensor = replace(default_sensor(), rpm=rpm, pitch_deg=pitch)
    origins, directions = window_rays(sensor, width, fov, np.array([phase]))
    assert directions.shape == (1, 16, width, 3)
    np.testing.assert_allclose(np.linalg.norm(directions, axis=-1), 1.0, atol=1e-12)
    assert np.isfinite(origins).all()


def test_elevations_and_origins_without_pitch():
    sensor = replace(default_sensor(), mount_height_m=1.5)
    origins, directions = window_rays(sensor, 16, 48.0, np.array([0.3]))
    rows = row_order(sensor)
    expected = np.deg2rad([sensor.elevations_deg[k] for k in rows])
    np.testing.assert_allclose(np.arcsin(directions[0, :, 0, 2]), expected, atol=1e-12)
    offsets = np.array([sensor.vertical_offsets_mm[k] for k in rows]) * 1e-3
    np.testing.assert_allclose(origins[0, :, 0, 2], 1.5 + offsets, atol=1e-12)
    np.testing.assert_allclose(origins[..., :2], 0.0, atol=1e-12)


def test_pitch_tilts_the_beams_down():
    level = window_rays(default_sensor(), 16, 48.0, np.array([0.0]))[1]
    tilted = window_rays(replace(default_sensor(), pitch_deg=5.0), 16, 48.0, np.array([0.0]))[1]
    # straight ahead, a beam at elevation e now points at e - 5 degrees
    centre = 8
    e0 = np.rad2deg(np.arcsin(level[0, :, centre, 2]))
    e1 = np.rad2deg(np.arcsin(tilted[0, :, centre, 2]))
    np.testing.assert_allclose(e1, e0 - 5.0, atol=0.05)


def test_centre_firing_lies_within_half_a_step_of_the_bin_centre():
    sensor = replace(default_sensor(), rpm=600)
    phase = np.linspace(0, 0.99, 7)
    azimuth = firing_azimuths_deg(sensor, 16, 48.0, phase)  # (7, 16, 16)
    centres = column_centres_deg(16, 48.0)
    rows = np.asarray(row_order(sensor))
    cycle_start = azimuth - rows[None, :, None] * sensor.firing_step_deg
    # every laser of a column belongs to the same firing cycle ...
    np.testing.assert_allclose(cycle_start - cycle_start[:, :1, :], 0.0, atol=1e-9)
    # ... the one whose start is nearest the bin centre
    assert np.abs(cycle_start[:, 0, :] - centres).max() <= sensor.azimuth_step_deg / 2 + 1e-9
    # and the column centres span the field of view evenly, left (negative) to right
    np.testing.assert_allclose(centres, -24 + 1.5 + 3 * np.arange(16))


def test_window_rays_follow_the_firing_azimuths():
    # the pulses' directions point where firing_azimuths_deg says: clockwise, positive = right
    sensor = replace(default_sensor(), rpm=1200)
    phase = np.array([0.1, 0.8])
    _, directions = window_rays(sensor, 16, 36.0, phase)
    azimuth = np.rad2deg(np.arctan2(-directions[..., 1], directions[..., 0]))
    np.testing.assert_allclose(azimuth, firing_azimuths_deg(sensor, 16, 36.0, phase), atol=1e-9)
    assert (directions[:, :, 0, 1] > 0).all()  # column 0 looks left (+y)
    assert (directions[:, :, -1, 1] < 0).all()  # the last column looks right (-y)


def test_lasers_fire_in_id_order_inside_a_cycle():
    sensor = replace(default_sensor(), rpm=1200)
    azimuth = firing_azimuths_deg(sensor, 4, 36.0, np.array([0.25]))[0]  # (16, 4)
    by_laser = np.empty_like(azimuth)
    by_laser[row_order(sensor)] = azimuth  # rows -> laser ids 0..15
    # laser j fires j x 2.304 us after laser 0: 0.0166 deg per laser at 1200 RPM
    np.testing.assert_allclose(np.diff(by_laser, axis=0), 360 * 20 * 2.304e-6, atol=1e-12)


def test_pitch_moves_the_upper_emitters_forward():
    # pitched down, an emitter above the reference point moves forward (+x), one below back
    origins = window_rays(replace(default_sensor(), pitch_deg=10.0), 4, 36.0, np.array([0.0]))[0][
        0, :, 0
    ]
    rows = row_order(default_sensor())
    offsets = np.array([default_sensor().vertical_offsets_mm[k] for k in rows]) * 1e-3
    np.testing.assert_allclose(origins[:, 0], offsets * np.sin(np.deg2rad(10.0)), atol=1e-12)
    np.testing.assert_allclose(origins[:, 2], 1.8 + offsets * np.cos(np.deg2rad(10.0)))
