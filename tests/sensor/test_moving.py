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
    motion = PlanarMotion(speed_mps=20.0, heading_deg=180.0, origin_m=(15.0, 0.0))
    still = PlanarMotion().poses(t)
    hits = cast_moving(scene, origins, directions, np.array([5]), sensor.max_range_m, still,
                       motion, t)  # fmt: skip
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
    follows = PlanarMotion(speed_mps=10.0, origin_m=(15.0, 0.0))
    moving = cast_moving(scene, origins, directions, np.array([0]), 100.0, ego, follows, t)
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
    thing = PlanarMotion(speed_mps=3.0, heading_deg=90.0, origin_m=(15.0, 0.0))
    rays = np.concatenate([origins] * 2), np.concatenate([directions] * 2)
    both = cast_moving(two, *rays, np.array([2, 3]), 100.0, ego, thing, times, incidence=True)
    for k in (0, 1):
        alone = cast_moving(scene, origins, directions, np.array([2 + k]), 100.0,
                            PlanarMotion(8.0, 10.0).poses(times[k:k + 1]),
                            PlanarMotion(3.0, 0.0, 90.0, (15.0, 0.0)), times[k:k + 1],
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
    thing = PlanarMotion(6.0, 15.0, 90.0, (15.0, 2.0))
    forms = [
        cast_moving(
            scene,
            origins,
            directions,
            np.array([9]),
            100.0,
            ego,
            thing,
            t,
            incidence=True,
            compiled=compiled,
        )  # fmt: skip
        for compiled in (False, True)
    ]
    for name in ("range_m", "surface", "on_object", "cos_incidence"):
        np.testing.assert_array_equal(getattr(forms[0], name), getattr(forms[1], name), name)
    assert (forms[0].surface == CAR).sum() > 50


def test_the_object_cast_only_near_it_gives_the_hits_of_casting_every_ray():
    """The object is cast only with the rays that pass near it over the frame: its hits are
    those of casting every ray into its frame at its time, to the bit, for objects that turn,
    cross, come on fast, stand, or are absent (a batch of five frames, every pulse of each)."""
    from simlidar.sensor.moving import OBJECT_CELLS, nearest
    from simlidar.sensor.raycast import MAX_BATCH

    sensor = default_sensor()
    specs = [
        ((15.0, 2.0, 0.0), (4.0, 1.8, 1.5)),
        ((8.0, -3.0, 0.0), (0.6, 0.6, 1.8)),
        ((30.0, 0.0, 0.0), (10.0, 2.5, 3.5)),
        ((6.0, 1.0, 0.0), (4.0, 1.8, 1.5)),
    ]
    wall = ((40.5, 0.0, -5.0), (1.0, 200.0, 30.0), WALL, False)
    scenes = [_scene((at, size, CAR, True), wall) for at, size in specs] + [_scene(wall)]
    scene = SceneBatch(
        np.concatenate([s.triangles for s in scenes]),
        np.concatenate([s.surface for s in scenes]),
        np.concatenate([np.full(len(s.triangles), k) for k, s in enumerate(scenes)]),
        np.concatenate([s.closed for s in scenes]),
        np.concatenate([s.is_object for s in scenes]),
        np.zeros((5, 3)),
    )
    frames = [_frame(sensor, phase) for phase in (0.1, 0.3, 0.5, 0.7, 0.9)]
    origins, directions, t = (np.concatenate(parts) for parts in zip(*frames))
    t = t + np.arange(5)[:, None, None] * 0.1  # later frames of a sequence
    column = np.array([6.0, 1.5, 15.0, 0.0, 9.0])[:, None, None]
    things = PlanarMotion(column, np.array([30.0, 0.0, -5.0, 0.0, 0.0])[:, None, None],
                          np.array([90.0, -90.0, 180.0, 0.0, 0.0])[:, None, None],
                          (np.array([15.0, 8.0, 30.0, 6.0, 0.0])[:, None, None],
                           np.array([2.0, -3.0, 0.0, 1.0, 0.0])[:, None, None]))  # fmt: skip
    ego = PlanarMotion(speed_mps=10.0, yaw_rate_deg_s=5.0).poses(t)
    slots = np.arange(100, 105)
    got = cast_moving(scene, origins, directions, slots, 100.0, ego, things, t, incidence=True)
    # the reference: every ray cast against each body in one scene each, no filter
    world_o, world_d = ego.to_scene(origins), ego.rotate(directions)
    body = scene.is_object
    alone = [replace(scene, triangles=scene.triangles[keep], surface=scene.surface[keep],
                     sample=scene.sample[keep], closed=scene.closed[keep],
                     is_object=scene.is_object[keep]) for keep in (~body, body)]  # fmt: skip
    moved = things.poses(t)
    world = cast(alone[0], world_o, world_d, slots, 100.0, cull=False, incidence=True)
    thing = cast(alone[1], moved.to_body(world_o), moved.unrotate(world_d),
                 (slots + OBJECT_CELLS) % MAX_BATCH, 100.0, cull=False, incidence=True)  # fmt: skip
    want = nearest(world, thing)
    for name in ("range_m", "surface", "on_object", "cos_incidence"):
        np.testing.assert_array_equal(getattr(got, name), getattr(want, name), name)
    on_car = (want.surface == CAR).sum(axis=(1, 2))
    assert (on_car[:4] > 20).all() and on_car[4] == 0
