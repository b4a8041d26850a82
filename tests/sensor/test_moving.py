"""Casting in a moving world (issue 59): every pulse at its own emission time, against numbers
derived by hand."""

from dataclasses import replace

import numpy as np
import pytest

from simlidar.motion.poses import PlanarMotion
from simlidar.scene.build import SceneBatch
from simlidar.scene.primitives import box
from simlidar.sensor import default_sensor
from simlidar.sensor.moving import cast_moving
from simlidar.sensor.raycast import cast
from simlidar.sensor.rays import sweep_emission_ns, sweep_rays

WALL, CAR = 3, 7


def _scene(*specs) -> SceneBatch:
    """One sample of axis-aligned boxes: (bottom centre, size, surface, is the object) each."""
    tris, surface, is_object = [], [], []
    for at, size, label, thing in specs:
        tris.append(box().triangles * np.asarray(size, float) + np.asarray(at, float))
        surface += [label] * 12
        is_object += [thing] * 12
    t = np.concatenate(tris)
    return SceneBatch(t, np.array(surface, np.uint8), np.zeros(len(t), int),
                      np.ones(len(t), bool), np.array(is_object), np.zeros((1, 3)))  # fmt: skip


def _frame(sensor, phase=0.25):
    """A whole rotation's rays (1, H, C, 3) and each pulse's emission time (1, H, C), s."""
    origins, directions = sweep_rays(sensor, np.array([phase]))
    return origins, directions, sweep_emission_ns(sensor)[None] * 1e-9


def test_a_wall_seen_from_a_car_at_10_m_s():
    """A wall across the road, its face at x = 20 m; the VLP-16 at 600 RPM on a car at 10 m/s.
    Each pulse meets the plane x = 20 where its own emission time puts the sensor: range =
    (20 - x_origin - 10 t) / d_x. The wall is seen over +-78.5 deg of azimuth (where it lies
    within the 100 m range: cos(az) = 20 / 100), 43.6 ms of the 100 ms rotation, in which the car
    moves 0.436 m, and the wall's points move with it: v x 100 ms = 1 m over a whole rotation."""
    sensor = default_sensor()
    origins, directions, t = _frame(sensor)
    scene = _scene(((20.5, 0.0, -5.0), (1.0, 200.0, 30.0), WALL, False))
    ego = PlanarMotion(speed_mps=10.0).poses(t)
    hits = cast_moving(scene, origins, directions, np.array([0]), sensor.max_range_m, ego)
    on_wall = hits.surface == WALL
    expected = (20.0 - origins[..., 0] - 10.0 * t) / directions[..., 0]
    np.testing.assert_allclose(hits.range_m[on_wall], expected[on_wall], atol=1e-9)
    assert on_wall.sum() > 0.35 * on_wall.size  # 157 of 360 degrees, the lasers that reach
    # the perpendicular distance to the wall as each pulse saw it: 20 m less the car's travel
    seen = hits.range_m[on_wall] * directions[..., 0][on_wall] + origins[..., 0][on_wall]
    span_s = np.ptp(t[on_wall])
    assert span_s == pytest.approx(2 * np.degrees(np.arccos(0.2)) / 360 * 0.1, abs=0.001)
    assert np.ptp(20.0 - seen) == pytest.approx(10.0 * span_s, abs=1e-9)
    # standing still, the same pulses see the wall where a static cast does
    still = cast_moving(scene, origins, directions, np.array([0]), sensor.max_range_m,
                        PlanarMotion().poses(t))  # fmt: skip
    static = cast(scene, origins, directions, np.array([0]), sensor.max_range_m)
    np.testing.assert_array_equal(still.range_m, static.range_m)
    np.testing.assert_array_equal(still.surface, static.surface)


def test_a_car_driving_at_the_sensor_is_hit_where_it_is_at_each_pulse():
    """A car-sized box 15 m ahead coming at 20 m/s (heading 180 deg); the sensor stands. Its
    rear face, x = 13 m at t = 0, is at 13 - 20 t when a pulse leaves."""
    sensor = default_sensor()
    origins, directions, t = _frame(sensor)
    scene = _scene(
        ((15.0, 0.0, 0.0), (4.0, 1.8, 1.5), CAR, True),  # its near face at x = 13 m
        ((60.5, 0.0, -5.0), (1.0, 200.0, 30.0), WALL, False),
    )
    motion = PlanarMotion(speed_mps=20.0, heading_deg=180.0, origin_m=(15.0, 0.0)).poses(t)
    still = PlanarMotion().poses(t)
    hits = cast_moving(scene, origins, directions, np.array([5]), sensor.max_range_m, still,
                       motion)  # fmt: skip
    on_car = hits.surface == CAR
    assert on_car.sum() > 50 and hits.on_object[on_car].all() and not hits.on_object[~on_car].any()
    near = on_car & (directions[..., 0] > 0.99)  # pulses nearly straight ahead: the near face
    expected = (13.0 - 20.0 * t - origins[..., 0]) / directions[..., 0]
    np.testing.assert_allclose(hits.range_m[near], expected[near], atol=1e-9)
    # the wall behind is seen where the car is not, whatever the car's motion
    np.testing.assert_allclose(
        hits.range_m[hits.surface == WALL],
        ((60.0 - origins[..., 0]) / directions[..., 0])[hits.surface == WALL],
        atol=1e-9,
    )


def test_a_moving_object_seen_from_a_moving_car():
    """Both move the same: car and object at 10 m/s ahead, so the object keeps its distance; a
    pulse sees it exactly as a static cast of the same pair does."""
    sensor = default_sensor()
    origins, directions, t = _frame(sensor)
    scene = _scene(((15.0, 0.0, 0.0), (4.0, 1.8, 1.5), CAR, True))
    ego = PlanarMotion(speed_mps=10.0).poses(t)
    follows = PlanarMotion(speed_mps=10.0, origin_m=(15.0, 0.0)).poses(t)
    moving = cast_moving(scene, origins, directions, np.array([0]), 100.0, ego, follows)
    static = cast(scene, origins, directions, np.array([0]), 100.0)
    hit = ~np.isnan(static.range_m)
    assert hit.sum() > 50
    np.testing.assert_array_equal(np.isnan(moving.range_m), ~hit)
    np.testing.assert_allclose(moving.range_m[hit], static.range_m[hit], atol=1e-9)
    assert (moving.surface == static.surface).all()


def test_a_batch_of_frames_is_the_frames_one_at_a_time():
    sensor = default_sensor()
    origins, directions, t = _frame(sensor)
    scene = _scene(((15.0, 0.0, 0.0), (4.0, 1.8, 1.5), CAR, True),
                   ((40.5, 0.0, -5.0), (1.0, 200.0, 30.0), WALL, False))  # fmt: skip
    two = replace(
        scene,
        triangles=np.concatenate([scene.triangles] * 2),
        surface=np.concatenate([scene.surface] * 2),
        sample=np.repeat([0, 1], len(scene.sample)),
        closed=np.concatenate([scene.closed] * 2),
        is_object=np.concatenate([scene.is_object] * 2),
        object_pose=np.zeros((2, 3)),
    )
    times = np.concatenate([t, t + 0.1])  # frame 1 a rotation later
    ego = PlanarMotion(speed_mps=8.0, yaw_rate_deg_s=10.0).poses(times)
    thing = PlanarMotion(speed_mps=3.0, heading_deg=90.0, origin_m=(15.0, 0.0)).poses(times)
    rays = np.concatenate([origins] * 2), np.concatenate([directions] * 2)
    both = cast_moving(two, *rays, np.array([2, 3]), 100.0, ego, thing, incidence=True)
    for k in (0, 1):
        alone = cast_moving(scene, origins, directions, np.array([2 + k]), 100.0,
                            PlanarMotion(8.0, 10.0).poses(times[k:k + 1]),
                            PlanarMotion(3.0, 0.0, 90.0, (15.0, 0.0)).poses(times[k:k + 1]),
                            incidence=True)  # fmt: skip
        np.testing.assert_array_equal(both.range_m[k], alone.range_m[0])
        np.testing.assert_array_equal(both.surface[k], alone.surface[0])
        np.testing.assert_array_equal(both.cos_incidence[k], alone.cos_incidence[0])


def test_the_compiled_kernels_give_the_same_hits():
    """Long runs cast through the compiled kernels (raycast.compiled_for): the same bits."""
    sensor = default_sensor()
    origins, directions, t = _frame(sensor)
    scene = _scene(((15.0, 2.0, 0.0), (4.0, 1.8, 1.5), CAR, True),
                   ((40.5, 0.0, -5.0), (1.0, 200.0, 30.0), WALL, False))  # fmt: skip
    ego = PlanarMotion(speed_mps=12.0, yaw_rate_deg_s=-20.0).poses(t)
    thing = PlanarMotion(6.0, 15.0, 90.0, (15.0, 2.0)).poses(t)
    forms = [
        cast_moving(
            scene,
            origins,
            directions,
            np.array([9]),
            100.0,
            ego,
            thing,
            incidence=True,
            compiled=compiled,
        )  # fmt: skip
        for compiled in (False, True)
    ]
    for name in ("range_m", "surface", "on_object", "cos_incidence"):
        np.testing.assert_array_equal(getattr(forms[0], name), getattr(forms[1], name), name)
    assert (forms[0].surface == CAR).sum() > 50
