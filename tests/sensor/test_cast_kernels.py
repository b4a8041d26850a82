"""The cast's compiled kernels against its numpy form, bit for bit: every dataset's bytes depend
on it (long runs cast with the kernels, short ones with numpy). Whole datasets compare the
scene building's kernel and the random streams' too (tests/scene/test_build_kernels.py and
tests/generator/test_streams.py compare them alone)."""

from dataclasses import replace

import numpy as np
import pytest

from simlidar.generator import stream_kernels as streams
from simlidar.generator.config import GeneratorConfig
from simlidar.generator.generate import generate
from simlidar.generator.profiles import load_profile
from simlidar.scene import kernels as scene_kernels
from simlidar.scene.build import SceneBatch
from simlidar.sensor import cast_kernels, raycast, window_rays
from simlidar.sensor.embree import shared_buffers
from simlidar.sensor.model import default_sensor, load_sensor
from simlidar.sensor.raycast import cast, cell_offsets, visible_triangles
from simlidar.sensor.rays import sweep_rays


def same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    """Equal to the last bit (NaN's payload and the sign of zero included)."""
    a, b = np.ascontiguousarray(a), np.ascontiguousarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


def catalog_batch(scene_batch, n: int, seed: int):
    """n scenes of every layout and object, with the VLP-16's window rays."""
    rng = np.random.default_rng(seed)
    layout, obj = rng.integers(0, 8, n), rng.integers(0, 4, n)
    scene = scene_batch(layout, obj, rng)
    origins, directions = window_rays(default_sensor(), 16, 36.0, rng.random(n))
    return scene, origins, directions


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_culling_kernel_is_numpys_to_the_bit(scene_batch, seed):
    scene, origins, _ = catalog_batch(scene_batch, 300, seed)
    keep, normal, plane = visible_triangles(scene, origins, compiled=True)
    want = visible_triangles(scene, origins)
    assert 0.2 < keep.mean() < 0.8  # some faces culled, some kept: a real comparison
    for got, ref in zip((keep, normal, plane), want, strict=True):
        assert same_bits(got, ref)


def test_culling_agrees_on_degenerate_signed_zero_and_nan_triangles():
    rng = np.random.default_rng(3)
    tris = rng.normal(size=(400, 3, 3)) * 30
    tris[:50, 2] = tris[:50, 1]  # degenerate: two equal corners
    tris[50:100] = np.round(tris[50:100])  # exact products, exact cancellations
    tris[100:150, :, 2] = -0.0  # flat in z: signed-zero products in the normal and plane
    tris[150:160, 0, 0] = np.nan
    tris[160:170] *= 1e-160  # products that underflow
    closed = rng.random(400) < 0.7
    scene = SceneBatch(
        tris,
        np.zeros(400, np.uint8),
        np.zeros(400, np.int64),
        closed,
        np.zeros(400, bool),
        np.full((1, 3), np.nan),
    )
    origins = np.array([[0.0, 0.0, -0.5], [0.0, 0.0, 0.7]]).reshape(1, 2, 1, 3)
    got = visible_triangles(scene, origins, compiled=True)
    for g, ref in zip(got, visible_triangles(scene, origins), strict=True):
        assert same_bits(g, ref)
    assert not got[0][:50].any() and got[0][50:].any()


@pytest.mark.parametrize("name", ["vlp16", "hdl32e", "hdl64e"])
@pytest.mark.parametrize("pitch", [0.0, 3.5])
def test_the_compiled_rays_are_numpys_to_the_bit(name, pitch):
    sensor = replace(load_sensor(name), pitch_deg=pitch)
    phase = np.random.default_rng(5).random(40)
    for got, want in zip(
        window_rays(sensor, 16, 36.0, phase, compiled=True),
        window_rays(sensor, 16, 36.0, phase),
        strict=True,
    ):
        assert same_bits(got, want)
    for got, want in zip(
        sweep_rays(sensor, phase[:2], compiled=True), sweep_rays(sensor, phase[:2]), strict=True
    ):
        assert same_bits(got, want)


@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize("shared", [True, False])
def test_the_compiled_cast_is_the_numpy_casts_to_the_bit(scene_batch, seed, shared):
    scene, origins, directions = catalog_batch(scene_batch, 256, seed)
    slots = np.arange(256) * 13 + seed
    args = scene, origins, directions, slots, 100.0
    got = cast(*args, shared=shared, incidence=True, compiled=True)
    want = cast(*args, shared=shared, incidence=True)
    assert np.isfinite(want.range_m).mean() > 0.5  # most pulses return: a real comparison
    for name in ("range_m", "surface", "on_object", "cos_incidence"):
        assert same_bits(getattr(got, name), getattr(want, name)), name
    assert cast(*args, compiled=True).cos_incidence is None


@pytest.mark.skipif(not shared_buffers(), reason="the packed vertices go to the shared path")
def test_packed_vertices_and_ray_origins_are_numpys_float32_rounding(scene_batch):
    scene, origins, _ = catalog_batch(scene_batch, 64, 4)
    offsets = cell_offsets(np.arange(64) * 5)
    keep = np.flatnonzero(visible_triangles(scene, origins)[0])
    vertices = cast_kernels.pack_vertices(scene.triangles, keep, scene.sample, offsets)
    world = scene.triangles[keep] + offsets[scene.sample[keep]][:, None, :]
    assert same_bits(vertices[:, :3], world.reshape(-1, 3).astype(np.float32))
    assert not vertices[:, 3].any()
    assert same_bits(
        cast_kernels.ray_origins(origins.reshape(64, -1, 3), offsets),
        (origins + offsets[:, None, None, :]).reshape(-1, 3).astype(np.float32),
    )


@pytest.mark.parametrize(
    "profile, options",
    [("physical", {}), ("sensor", {"return_mode": "dual", "fog_visibility_m": 50.0})],
)
def test_a_long_run_writes_the_bytes_of_a_short_one(
    catalog, tmp_path, monkeypatch, profile, options
):
    config = GeneratorConfig.from_profile(
        load_profile(profile), train_size=96, test_size=32, **options
    )
    rays = 128 * 16 * 16

    def make(out):
        (written,) = generate(config, [0.1], catalog, out, progress=False, preview=False)
        return written.path

    calls = []  # the kernels' calls: which path each run took
    kernels = (cast_kernels, "first_hits"), (scene_kernels, "place_copies"), (streams, "draw")
    for module, name in kernels:
        kernel = getattr(module, name)
        monkeypatch.setattr(module, name, lambda *a, k=kernel, n=name: calls.append(n) or k(*a))
    assert not raycast.compiled_for(rays)
    short = make(tmp_path / "numpy")
    assert not calls
    monkeypatch.setattr(raycast, "COMPILED_FROM_RAYS", rays)  # this run counts as long
    long = make(tmp_path / "compiled")
    assert set(calls) == {"first_hits", "place_copies", "draw"}  # scenes and draws too
    files = sorted(p.relative_to(short) for p in short.rglob("*") if p.is_file())
    assert len(files) >= 4  # train.h5, test.h5, the card, the checksums
    assert files == sorted(p.relative_to(long) for p in long.rglob("*") if p.is_file())
    for name in files:
        assert (short / name).read_bytes() == (long / name).read_bytes(), name


def test_a_ray_on_another_samples_triangle_is_reported():
    normal, plane = np.array([[1.0, 0.0, 0.0]]), np.array([5.0])
    origins = np.zeros((2, 1, 3))
    directions = np.tile([1.0, 0.0, 0.0], (2, 1, 1))
    args = normal, plane, origins, directions, np.array([1]), np.array([3], np.uint8)
    prim = np.array([-1, 0], np.int32)  # sample 1's ray hits triangle 0, of sample 1
    r, s, o, c, isolated = cast_kernels.first_hits(prim, np.array([0]), *args, np.array([True]))
    assert isolated and np.isnan(r[0]) and r[1] == 5.0 and s[1] == 3 and o[1] and c[1] == 1.0
    prim = np.array([0, -1], np.int32)  # sample 0's ray hits it
    assert not cast_kernels.first_hits(prim, np.array([0]), *args, np.array([True]))[-1]
