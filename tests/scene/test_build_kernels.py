"""Scene building's compiled kernel against its numpy form, bit for bit: long runs build their
scenes with the kernel, short ones with numpy, and a dataset's bytes must not depend on which."""

from dataclasses import replace

import numpy as np
import pytest

from simlidar.scene.build import CELL_HALF_EXTENT_M, Instances, build_batch, instance_triangles
from simlidar.scene.kernels import place_copies
from simlidar.scene.primitives import template

FIELDS = ("triangles", "surface", "sample", "closed", "is_object", "object_pose")


def same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    """Equal to the last bit (NaN's payload and the sign of zero included)."""
    a, b = np.ascontiguousarray(a), np.ascontiguousarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("variation", [1.0, 0.25])
def test_the_compiled_scenes_are_numpys_to_the_bit(catalog, seed, variation):
    catalog = catalog.with_variation(variation)
    rng = np.random.default_rng(seed)
    n = 400
    layout, obj = rng.integers(0, 8, n), rng.integers(0, 4, n)
    args = (
        catalog,
        layout,
        obj,
        rng.random((n, catalog.layout_columns)),
        rng.random((n, catalog.object_columns)),
    )
    want, got = build_batch(*args), build_batch(*args, compiled=True)
    assert len(want.triangles) > 100 * n  # every layout and object: a real comparison
    assert set(np.unique(layout)) == set(range(8)) and set(np.unique(obj)) == set(range(4))
    for name in FIELDS:
        assert same_bits(getattr(got, name), getattr(want, name)), name


@pytest.mark.parametrize("kind, segments", [("box", 0), ("cylinder", 6), ("arch", 12)])
def test_the_kernel_repeats_the_products_order_with_signed_zeros_and_extremes(
    catalog, kind, segments
):
    rng = np.random.default_rng(7)
    m = 64
    yaw = rng.uniform(-360, 360, m)
    yaw[:8] = [0.0, -0.0, 90.0, 180.0, -90.0, 270.0, 360.0, 45.0]  # exact and signed zeros
    size = rng.uniform(0.01, 40.0, (m, 3))
    size[8:16] = 5e-324  # the least subnormal: the products underflow to signed zeros
    at = rng.uniform(-100, 100, (m, 3))
    at[8:24] = -0.0  # a signed zero added to the products
    prim = replace(catalog.objects[1].primitives[0], kind=kind, segments=segments)
    inst = Instances(prim, np.zeros(m, np.int64), at, size, yaw, False)
    want = instance_triangles(inst).reshape(-1, 3, 3)
    shape = template(kind, segments).triangles
    got = np.empty_like(want)
    rad = np.deg2rad(yaw)
    inside = place_copies(shape, np.cos(rad), np.sin(rad), size, at, CELL_HALF_EXTENT_M, got)
    assert same_bits(got, want)
    assert inside == bool(np.abs(want).max() <= CELL_HALF_EXTENT_M)
    # a real comparison: the same products one operation at a time round otherwise
    c, s = np.cos(rad)[:, None, None], np.sin(rad)[:, None, None]
    v = np.broadcast_to(shape, (m, *shape.shape))
    x = v[..., 0] * (c * size[:, None, None, 0]) + v[..., 1] * (-s * size[:, None, None, 1])
    plain = (x + v[..., 2] * 0.0) + at[:, None, None, 0]
    assert same_bits(plain, want[..., 0].reshape(x.shape)) == (kind == "box")


@pytest.mark.parametrize("value", [np.nan, np.inf, 150.001, -151.0])
def test_the_kernel_says_when_a_vertex_leaves_the_cell(catalog, value):
    prim = catalog.objects[1].primitives[0]
    at = np.array([[0.0, 0.0, 0.0], [1.0, value, 0.0]])
    size, yaw = np.ones((2, 3)), np.zeros(2)
    got = np.empty((24, 3, 3))
    assert not place_copies(template("box", 0).triangles, np.cos(yaw), np.sin(yaw), size, at,
                            CELL_HALF_EXTENT_M, got)  # fmt: skip
    at[1, 1] = 149.0
    assert place_copies(template("box", 0).triangles, np.cos(yaw), np.sin(yaw), size, at,
                        CELL_HALF_EXTENT_M, got)  # fmt: skip
    inst = Instances(prim, np.zeros(2, np.int64), at, size, yaw, True)
    assert same_bits(got, instance_triangles(inst).reshape(-1, 3, 3))
