"""Shared Embree buffers: the same hits as embreex's own copy, and a safe fallback."""

import sys

import numpy as np
import pytest

from simlidar.sensor import default_sensor, embree, window_rays
from simlidar.sensor.raycast import cast


def _batch(scene_batch, n, seed):
    rng = np.random.default_rng(seed)
    layout, obj = rng.integers(0, 8, n), rng.integers(0, 4, n)
    scene = scene_batch(layout, obj, rng)
    origins, directions = window_rays(default_sensor(), 16, 36.0, rng.random(n))
    return scene, origins, directions


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="tested on Linux")
def test_the_shared_path_is_on_where_embreex_ships_its_library():
    assert embree.shared_buffers()


@pytest.mark.parametrize("seed", [0, 1])
def test_hits_equal_embreex_triangle_mesh(scene_batch, seed):
    scene, origins, directions = _batch(scene_batch, 256, seed)
    slots = np.arange(256) * 7 + seed
    a = cast(scene, origins, directions, slots, 100.0, shared=True)
    b = cast(scene, origins, directions, slots, 100.0, shared=False)
    assert (~np.isnan(a.range_m)).mean() > 0.5  # most pulses return: a real comparison
    np.testing.assert_array_equal(a.range_m, b.range_m)
    np.testing.assert_array_equal(a.surface, b.surface)
    np.testing.assert_array_equal(a.on_object, b.on_object)


def test_buffers_hold_the_float32_triangles():
    if not embree.shared_buffers():
        pytest.skip("shared buffers unavailable here")
    tris = np.random.default_rng(0).normal(size=(5, 3, 3)) * 10
    vertices, indices = embree.attach_triangles(embree.new_scene(), tris)
    np.testing.assert_array_equal(vertices[:, :3], tris.reshape(-1, 3).astype(np.float32))
    np.testing.assert_array_equal(indices, np.arange(15).reshape(5, 3))


def test_an_unexpected_layout_turns_the_shared_path_off():
    import embreex.rtcore as rtc
    import embreex.rtcore_scene as rtcs

    class Bigger(rtcs.EmbreeScene):  # a subclass with a __dict__ has another C layout
        pass

    device = rtc.EmbreeDevice()
    assert not embree._layout_ok(Bigger, device)
    assert embree._layout_ok(rtcs.EmbreeScene, device)


def test_a_surprise_while_probing_turns_the_shared_path_off(monkeypatch):
    def unlike(*_):
        raise AttributeError("an embreex unlike the one known")

    monkeypatch.setattr(embree, "_open", unlike)
    embree._probe.cache_clear()
    try:
        assert not embree.shared_buffers()
        assert embree.ray_casting() == (
            "embreex's TriangleMesh, a copy a triangle: slower, the same hits (probing embreex "
            "raised AttributeError: an embreex unlike the one known)"
        )
    finally:
        embree._probe.cache_clear()


def test_only_an_embreex_scene_is_accepted():
    if not embree.shared_buffers():
        pytest.skip("shared buffers unavailable here")
    with pytest.raises(TypeError, match="expected an embreex EmbreeScene, got object"):
        embree.attach_triangles(object(), np.ones((1, 3, 3)))


def test_without_the_shared_path_the_cast_falls_back_and_says_so_once(scene_batch, monkeypatch):
    scene, origins, directions = _batch(scene_batch, 32, 2)
    slots = np.arange(32)
    expected = cast(scene, origins, directions, slots, 100.0)
    monkeypatch.setattr(embree, "_embree", lambda: None)
    assert not embree.shared_buffers()
    embree._say_fallback.cache_clear()
    try:
        with pytest.warns(UserWarning, match="ray casting through embreex's TriangleMesh") as said:
            got = cast(scene, origins, directions, slots, 100.0)
            cast(scene, origins, directions, slots, 100.0)
    finally:
        embree._say_fallback.cache_clear()
    assert len(said) == 1  # once a process, not once a batch
    np.testing.assert_array_equal(got.range_m, expected.range_m)


def test_the_version_says_which_ray_casting_path_is_in_use(monkeypatch, cli):

    shared = cli("--version")
    assert shared.exit_code == 0
    assert shared.stdout.splitlines()[1] == f"ray casting: {embree.ray_casting()}"
    monkeypatch.setattr(embree, "_probe", lambda: (None, "embreex's Embree is version 3"))
    fallback = cli("--version")
    assert fallback.exit_code == 0
    assert fallback.stdout.splitlines()[1] == (
        "ray casting: embreex's TriangleMesh, a copy a triangle: slower, the same hits "
        "(embreex's Embree is version 3)"
    )


def test_vertices_in_another_layout_are_refused():
    if not embree.shared_buffers():
        pytest.skip("shared buffers unavailable here")
    for bad in (np.zeros((6, 4)), np.zeros((6, 3), np.float32), np.zeros((5, 4), np.float32),
                np.zeros((6, 8), np.float32)[:, ::2]):  # fmt: skip
        with pytest.raises(ValueError, match="expected"):
            embree.attach_vertices(embree.new_scene(), bad)
    vertices = np.zeros((6, 4), np.float32)
    assert embree.attach_vertices(embree.new_scene(), vertices)[0] is vertices
