import numpy as np

from simlidar.scene.build import CELL_HALF_EXTENT_M
from simlidar.scene.primitives import arch, box, cylinder


def test_templates_are_unit_shapes_on_their_origin():
    for t in (box(), cylinder(8), arch(12)):
        v = t.triangles.reshape(-1, 3)
        np.testing.assert_allclose(v.min(axis=0), [-0.5, -0.5, 0.0], atol=1e-12)
        np.testing.assert_allclose(v.max(axis=0), [0.5, 0.5, 1.0], atol=1e-12)


def test_closed_templates_wind_outward():
    for t in (box(), cylinder(6)):
        tri = t.triangles
        normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        outward = np.einsum("ij,ij->i", normal, tri.mean(axis=1) - [0, 0, 0.5])
        assert (outward > 0).all()


def test_a_batch_of_every_class(catalog, scene_batch):
    n = 64
    rng = np.random.default_rng(0)
    layout, obj = np.arange(n) % 8, np.arange(n) // 8 % 4
    batch = scene_batch(layout, obj, rng)
    assert batch.triangles.shape[1:] == (3, 3)
    assert set(np.unique(batch.sample)) == set(range(n))
    assert np.abs(batch.triangles).max() <= CELL_HALF_EXTENT_M
    # object triangles carry the object's surface and only appear where there is an object
    names = np.array(catalog.surfaces)[batch.surface[batch.is_object]]
    expected = np.array(catalog.object_names)[obj[batch.sample[batch.is_object]]]
    assert (names == expected).all()
    assert np.isnan(batch.object_pose[obj == 0]).all()
    pose = batch.object_pose[obj > 0]
    assert np.isfinite(pose).all()
    assert (pose[:, 0] >= 3.0).all() and (pose[:, 0] <= 25.0).all()  # distance ahead


def test_objects_stand_where_their_pose_says(scene_batch):
    rng = np.random.default_rng(1)
    n = 12
    batch = scene_batch(np.zeros(n, int), np.full(n, 1), rng)
    for k in range(n):
        car = batch.triangles[(batch.sample == k) & batch.is_object].reshape(-1, 3)
        x, y, _ = batch.object_pose[k]
        centre = (car.min(axis=0) + car.max(axis=0)) / 2
        assert abs(centre[1] - y) < 0.6 and abs(centre[0] - x) < 1.0
        assert car[:, 2].min() >= 0.0  # on the road, not under it
