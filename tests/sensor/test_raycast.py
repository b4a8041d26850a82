"""The batched caster against numbers derived by hand and against trimesh's own ray code."""

import math
from dataclasses import replace

import numpy as np
import pytest

from simlidar.errors import ConfigError
from simlidar.generator.config import GeneratorConfig
from simlidar.generator.pulses import delays_from_range, quantise_range
from simlidar.scene.build import SceneBatch
from simlidar.scene.primitives import box
from simlidar.sensor import default_sensor, row_order, window_rays
from simlidar.sensor.raycast import cast

WALL, ROAD = 3, 1


def boxes(*specs) -> SceneBatch:
    """A scene batch of axis-aligned boxes: (sample, bottom centre, size, surface) each."""
    tris, surface, sample = [], [], []
    for k, at, size, label in specs:
        tris.append(box().triangles * np.asarray(size, float) + np.asarray(at, float))
        surface += [label] * 12
        sample += [k] * 12
    n = max(s[0] for s in specs) + 1
    t = np.concatenate(tris)
    return SceneBatch(
        t,
        np.array(surface, np.uint8),
        np.array(sample),
        np.ones(len(t), bool),
        np.zeros(len(t), bool),
        np.full((n, 3), np.nan),
    )


def test_a_wall_ten_metres_ahead_returns_after_66_71_ns():
    scene = boxes((0, (10.5, 0, -5), (1, 100, 25), WALL))
    origins = np.array([0.0, 0.0, 1.8]).reshape(1, 1, 1, 3)
    directions = np.array([1.0, 0.0, 0.0]).reshape(1, 1, 1, 3)
    hits = cast(scene, origins, directions, np.array([0]), 100.0)
    r = quantise_range(hits.range_m, default_sensor())
    tof, delay = delays_from_range(r, default_sensor())
    assert r[0, 0, 0] == pytest.approx(10.0, abs=1e-9)
    assert tof[0, 0, 0] == pytest.approx(66.71, abs=0.005)
    assert delay[0, 0, 0] == pytest.approx(0.1, abs=1e-6)  # 10 m of a 100 m window
    assert hits.surface[0, 0, 0] == WALL


def test_every_pulse_of_a_window_against_a_wall():
    sensor = default_sensor()
    scene = boxes((0, (10.5, 0, -5), (1, 100, 25), WALL))
    origins, directions = window_rays(sensor, 16, 48.0, np.array([0.37]))
    hits = cast(scene, origins, directions, np.array([0]), sensor.max_range_m)
    # by hand: the plane x = 10 is met after 10 / d_x = 10 / (cos(elevation) cos(azimuth))
    expected = 10.0 / directions[0, ..., 0]
    np.testing.assert_allclose(hits.range_m[0], expected, atol=1e-9)
    assert (hits.surface == WALL).all()


def test_the_minus_15_degree_laser_meets_a_flat_road_at_h_over_sin_15():
    sensor = replace(default_sensor(), mount_height_m=1.8)
    scene = boxes((0, (50, 0, -1), (200, 200, 1), ROAD))
    origins, directions = window_rays(sensor, 16, 48.0, np.array([0.5]))
    r = quantise_range(cast(scene, origins, directions, np.array([0]), 100.0).range_m, sensor)
    row = row_order(sensor).index(0)  # laser 0 is the -15 degree one
    # its emitter sits 11.2 mm above the reference plane
    expected = (1.8 + 0.0112) / math.sin(math.radians(15.0))
    np.testing.assert_allclose(r[0, row], expected, atol=0.001 + 1e-9)  # 2 mm resolution


def test_nothing_beyond_the_range_limits():
    sensor = default_sensor()
    near = boxes((0, (0.8, 0, 1.0), (0.2, 4, 2), WALL))  # 0.7 m ahead: too near
    far = boxes((0, (120.5, 0, -5), (1, 400, 100), WALL))  # 120 m ahead: too far
    origins = np.array([0.0, 0.0, 1.8]).reshape(1, 1, 1, 3)
    directions = np.array([1.0, 0.0, 0.0]).reshape(1, 1, 1, 3)
    for scene in (near, far):
        r = quantise_range(cast(scene, origins, directions, np.array([0]), 100.0).range_m, sensor)
        assert np.isnan(r).all()


def _real_batch(scene_batch, n=48, seed=3):
    rng = np.random.default_rng(seed)
    scene = scene_batch(np.arange(n) % 8, np.arange(n) % 4, rng)
    origins, directions = window_rays(default_sensor(), 16, 48.0, rng.random(n))
    return scene, origins, directions


def test_culling_changes_nothing(scene_batch):
    scene, origins, directions = _real_batch(scene_batch)
    slots = np.arange(len(origins))
    a = cast(scene, origins, directions, slots, 100.0, cull=True)
    b = cast(scene, origins, directions, slots, 100.0, cull=False)
    np.testing.assert_array_equal(a.range_m, b.range_m)
    np.testing.assert_array_equal(a.surface, b.surface)


def test_agrees_with_trimesh_pure_numpy_ray_code(scene_batch):
    import trimesh
    from trimesh.ray.ray_triangle import RayMeshIntersector

    scene, origins, directions = _real_batch(scene_batch, n=16, seed=5)
    hits = cast(scene, origins, directions, np.arange(16), 100.0)
    agree = total = 0
    for k in range(16):
        tris = scene.triangles[scene.sample == k]
        mesh = trimesh.Trimesh(
            tris.reshape(-1, 3), np.arange(3 * len(tris)).reshape(-1, 3), process=False
        )
        o, d = origins[k].reshape(-1, 3), directions[k].reshape(-1, 3)
        index_tri, index_ray, where = RayMeshIntersector(mesh).intersects_id(
            o, d, multiple_hits=False, return_locations=True
        )
        reference = np.full(len(o), np.nan)
        reference[index_ray] = np.linalg.norm(where - o[index_ray], axis=1)
        reference[reference > 101.0] = np.nan
        mine = hits.range_m[k].reshape(-1)
        same = np.isclose(mine, reference, atol=1e-6) | (np.isnan(mine) & np.isnan(reference))
        agree += same.sum()
        total += len(o)
    assert agree / total >= 0.999, f"{total - agree} of {total} pulses disagree"


def test_scenes_of_one_batch_do_not_see_each_other():
    # Sample 0 stands in cell 0; sample 1 in cell 1, the next cell along +x. Sample 0 has a
    # wall 149 m ahead of its sensor, as near to cell 1 as the 150 m bound allows, and a post
    # 50 m ahead; sample 1 looks backwards, straight at them, and must see nothing: its ray
    # stops at 101 m and the cells are 320 m apart.
    from simlidar.sensor.raycast import cell_offsets

    assert cell_offsets(np.array([1]))[0, 0] - cell_offsets(np.array([0]))[0, 0] > 0
    scene = boxes(
        (0, (149.5, 0, -5), (1, 290, 25), WALL),
        (0, (50.5, 0, 0), (1, 2, 3), WALL),
        (1, (0, 0, -140), (1, 1, 1), ROAD),
    )
    origins = np.broadcast_to(np.array([0.0, 0.0, 1.8]), (2, 1, 1, 3)).copy()
    directions = np.array([1.0, 0.0, 0.0]) * np.array([1, -1])[:, None]  # 0 ahead, 1 back
    directions = np.broadcast_to(directions[:, None, None, :], (2, 1, 1, 3)).copy()
    hits = cast(scene, origins, directions, np.array([0, 1]), 100.0)
    assert hits.range_m[0, 0, 0] == pytest.approx(50.0)  # sample 0 sees its own post
    assert np.isnan(hits.range_m[1]).all()
    # but a sensor that reaches farther than the cells allow is refused
    with pytest.raises(ConfigError, match="max range 250"):
        cast(scene, origins, directions, np.array([0, 1]), 250.0)


def test_the_default_config_keeps_scenes_apart():
    # the grid spacing must exceed the reach of a ray plus the extent of a scene
    from simlidar.scene.build import CELL_HALF_EXTENT_M
    from simlidar.sensor.raycast import CELL_SPACING_M

    assert CELL_SPACING_M > CELL_HALF_EXTENT_M + GeneratorConfig().sensor.max_range_m
