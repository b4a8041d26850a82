"""Batched ray casting: the scenes of a whole batch in one Embree scene, all rays in one call.

Each scene of the batch is moved into its own cell of a 16 x 16 x 16 grid spaced 320 m apart.
Scene geometry stays within 150 m of its sensor (checked by the scene builder) and rays stop at
the maximum range, so no ray can reach a neighbouring cell. A sample's cell is fixed by its
index in the split (``index mod 4096``), not by its place in the batch, so the float32
coordinates Embree sees, and therefore which triangle each ray hits, do not depend on the batch
size. The distance to the hit is then recomputed in float64 in the sample's local frame.

Before building the Embree scene, the faces of closed solids that are turned away from every
laser origin are dropped: no ray can hit them first, so this changes nothing but Embree's
per-triangle cost (its BVH build, and embreex's copy where the shared buffers of
:mod:`simlidar.sensor.embree` are unavailable), which it cuts by 60 %. Tests for
the horizontal wedge, the vertical beam cones and the range limit were tried and removed: they
cost more numpy time than the few triangles they drop save.

Two forms give the same hits to the last bit: numpy's, and compiled kernels
(:mod:`simlidar.sensor.cast_kernels`: culling, packing and the exact range in one pass each,
1.7 times faster for the whole cast, Embree included; the rays too,
:func:`simlidar.sensor.rays.window_rays`). The kernels cost a process about 0.4 s
of CPU time and 100 MB of memory to load (numba and LLVM), so they pay only on long runs:
:func:`compiled_for` says when, from the number of rays a process will cast
(docs/performance.md).
"""

from dataclasses import dataclass

import numpy as np

from simlidar.errors import ConfigError
from simlidar.scene.build import CELL_HALF_EXTENT_M, SceneBatch
from simlidar.sensor.embree import attach_triangles, attach_vertices, new_scene, shared_buffers

GRID_CELLS = 16  # per axis
# A ray reaches at most max range + 1 m from an origin near the cell centre; a neighbour's
# geometry starts CELL_SPACING_M - CELL_HALF_EXTENT_M away. cast() checks the margin.
CELL_SPACING_M = 320.0
MAX_BATCH = GRID_CELLS**3
# From this many rays a process casts, the compiled kernels save more than they cost to load:
# 0.34-0.41 s of loading against 0.10-0.13 us saved a ray pays from 3.2-3.5 M rays
# (`benchmark/cast_speed.py`; `simlidar generate` of 22,400 samples, 5.7 M rays, took 0.96 of
# the numpy form's time, of 100,000 0.84-0.88; docs/performance.md).
COMPILED_FROM_RAYS = 4_000_000


@dataclass(frozen=True)
class Hits:
    """What each pulse of B windows hits first."""

    range_m: np.ndarray  # (B, H, W) float64, NaN where nothing is hit
    surface: np.ndarray  # (B, H, W) uint8, 0 where nothing is hit
    on_object: np.ndarray  # (B, H, W) bool, the hit belongs to the labelled object
    # (B, H, W) float32, |cos| of the angle between the ray and the hit surface's normal, 0
    # where nothing is hit; only when cast(..., incidence=True), else None
    cos_incidence: np.ndarray | None = None


def cell_offsets(slots: np.ndarray) -> np.ndarray:
    """World offset of each grid cell: (B,) int in [0, MAX_BATCH) -> (B, 3) float64."""
    ijk = np.stack(
        [slots % GRID_CELLS, slots // GRID_CELLS % GRID_CELLS, slots // GRID_CELLS**2], axis=-1
    )
    return (ijk - GRID_CELLS // 2) * CELL_SPACING_M


def compiled_for(rays: int) -> bool:
    """Whether a process that casts ``rays`` rays in all should use the compiled kernels."""
    return rays >= COMPILED_FROM_RAYS


def visible_triangles(scene: SceneBatch, origins: np.ndarray, compiled: bool = False):
    """Mask (T,) of the triangles a ray could hit first; normals (T, 3) and planes (T,) of all.

    Triangle k lies in the plane ``normal[k] . x = plane[k]``.

    Drops the back faces of closed solids and degenerate triangles.

    A ray from outside a closed solid enters it through a face turned towards the ray's origin,
    so a face turned away from every origin is never a first hit and dropping it changes
    nothing. The origins of a window lie on one short segment (the lasers' vertical offsets),
    so a face turned away from both ends of the segment is turned away from all of them.
    Degenerate (zero-area) triangles are dropped too.

    compiled : by the compiled kernel (the same numbers)
    """
    tris = scene.triangles
    flat = origins.reshape(-1, 3)
    ends = flat[[np.argmin(flat[:, 2]), np.argmax(flat[:, 2])]]  # (2, 3)
    if compiled:
        from simlidar.sensor import cast_kernels

        return cast_kernels.cull(np.ascontiguousarray(tris, np.float64), scene.closed, ends)
    e1, e2 = tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    normal = np.stack(
        [
            e1[:, 1] * e2[:, 2] - e1[:, 2] * e2[:, 1],
            e1[:, 2] * e2[:, 0] - e1[:, 0] * e2[:, 2],
            e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0],
        ],
        axis=-1,
    )
    plane = np.einsum("tk,tk->t", normal, tris[:, 0])
    facing = normal @ ends.T - plane[:, None]  # (T, 2)
    back = scene.closed & (facing <= 0).all(axis=1)
    return ~back & normal.any(axis=1), normal, plane


def cast(
    scene: SceneBatch,
    origins: np.ndarray,
    directions: np.ndarray,
    slots: np.ndarray,
    max_range_m: float,
    cull: bool = True,
    shared: bool = True,
    incidence: bool = False,
    compiled: bool = False,
) -> Hits:
    """First hit of every pulse.

    scene : the batch's triangles, each tagged with its sample, surface and solid
        (:func:`simlidar.scene.build.build_batch`)
    origins, directions : (B, H, W, 3) float64 in each sample's local frame, unit directions
    slots : (B,) int, distinct grid cells (use the sample index in its split mod MAX_BATCH)
    max_range_m : the sensor's range: a ray stops there
    cull : drop triangles no ray can hit first (exact; off only to test that it is)
    shared : hand the triangles to Embree in place (:mod:`simlidar.sensor.embree`; off only to
        test that the hits are those of embreex's own copy)
    incidence : also give each hit's |cos incidence| (an intensity proxy: full sweeps)
    compiled : by the compiled kernels (the same hits, to the last bit; :func:`compiled_for`)
    """
    batch = origins.shape[0]
    if len(np.unique(slots)) != batch or not 0 <= np.min(slots) <= np.max(slots) < MAX_BATCH:
        raise ValueError(f"need {batch} distinct slots in [0, {MAX_BATCH}), got {slots!r}")
    reach = max_range_m + 1.0 + np.abs(origins).max()
    if reach + CELL_HALF_EXTENT_M >= CELL_SPACING_M:
        raise ConfigError(
            f"max range {max_range_m} m from origins up to {np.abs(origins).max():.1f} m off "
            f"the cell centre: expected rays to stay within "
            f"{CELL_SPACING_M - CELL_HALF_EXTENT_M:.0f} m of it"
        )
    mask, normal, plane = visible_triangles(scene, origins, compiled)
    keep = np.nonzero(mask if cull else normal.any(axis=1))[0]
    offsets = cell_offsets(np.asarray(slots))  # (B, 3)

    shape = origins.shape[:-1]
    if len(keep) == 0:
        cos_incidence = np.zeros(shape, np.float32) if incidence else None
        return Hits(np.full(shape, np.nan), np.zeros(shape, np.uint8), np.zeros(shape, bool),
                    cos_incidence)  # fmt: skip
    if compiled:
        return _compiled_hits(scene, origins, directions, offsets, max_range_m, shared, incidence,
                              keep, normal, plane)  # fmt: skip

    tris = np.take(scene.triangles, keep, axis=0)
    sample = np.take(scene.sample, keep)
    embree_scene = new_scene()
    world = tris + np.take(offsets, sample, axis=0)[:, None, :]
    buffers = attach_triangles(embree_scene, world, shared)
    ray_origin = (origins + offsets[:, None, None, :]).reshape(-1, 3).astype(np.float32)
    prim = _run(embree_scene, buffers, ray_origin, directions, max_range_m).reshape(shape)

    hit_range = np.full(shape, np.nan)
    surface = np.zeros(shape, np.uint8)
    on_object = np.zeros(shape, bool)
    cos_incidence = np.zeros(shape, np.float32) if incidence else None
    hit = prim >= 0
    flat = np.flatnonzero(hit)
    k = keep[prim.reshape(-1)[flat]]  # the hit triangle of each hitting ray
    if (scene.sample[k] != flat // (shape[1] * shape[2])).any():
        raise RuntimeError(_NOT_ISOLATED)
    # Exact distance in float64: where the ray meets the hit triangle's plane.
    n = np.take(normal, k, axis=0)
    o = np.take(origins.reshape(-1, 3), flat, axis=0)  # np.take: ~3x faster than a[flat]
    d = np.take(directions.reshape(-1, 3), flat, axis=0)
    n_dot_d = np.einsum("ij,ij->i", n, d)
    hit_range[hit] = (plane[k] - np.einsum("ij,ij->i", n, o)) / n_dot_d
    surface[hit] = scene.surface[k]
    on_object[hit] = scene.is_object[k]
    if incidence:
        cos_incidence[hit] = np.abs(n_dot_d) / np.sqrt(np.einsum("ij,ij->i", n, n))
    return Hits(hit_range, surface, on_object, cos_incidence)


_NOT_ISOLATED = "a ray hit another sample's scene: the cell isolation is broken"


def _run(embree_scene, buffers, ray_origin, directions, max_range_m):
    """Embree's first hits (primitive ids, -1: none) of float32 rays; the scene and its
    buffers are released after the run (Embree read them when it built the BVH)."""
    ray_dir = directions.reshape(-1, 3).astype(np.float32)
    far = np.full(len(ray_origin), max_range_m + 1.0, np.float32)
    prim = embree_scene.run(ray_origin, ray_dir, dists=far)
    del embree_scene, buffers
    return prim


def _compiled_hits(scene, origins, directions, offsets, max_range_m, shared, incidence, keep,
                   normal, plane):  # fmt: skip
    """The rest of :func:`cast` by the compiled kernels, from the culling pass's results."""
    from simlidar.sensor import cast_kernels

    embree_scene = new_scene()
    if shared and shared_buffers():
        vertices = cast_kernels.pack_vertices(scene.triangles, keep, scene.sample, offsets)
        buffers = attach_vertices(embree_scene, vertices)
    else:  # embreex's own copy of the same float32 vertices
        world = np.take(scene.triangles, keep, axis=0)
        world += np.take(offsets, np.take(scene.sample, keep), axis=0)[:, None, :]
        buffers = attach_triangles(embree_scene, world, shared)
    per_sample = (len(offsets), -1, 3)
    local_origins = origins.reshape(per_sample)
    ray_origin = cast_kernels.ray_origins(local_origins, offsets)
    prim = _run(embree_scene, buffers, ray_origin, directions, max_range_m)
    hit_range, surface, on_object, cos, isolated = cast_kernels.first_hits(
        prim,
        keep,
        normal,
        plane,
        local_origins,
        directions.reshape(per_sample),
        scene.sample,
        scene.surface,
        scene.is_object,
    )
    if not isolated:
        raise RuntimeError(_NOT_ISOLATED)
    shape = origins.shape[:-1]
    hits = hit_range.reshape(shape), surface.reshape(shape), on_object.reshape(shape)
    return Hits(*hits, cos.reshape(shape) if incidence else None)
