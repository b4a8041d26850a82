"""Batched ray casting: the scenes of a whole batch in one Embree scene, all rays in one call.

Each scene of the batch is moved into its own cell of a 16 x 16 x 16 grid spaced 256 m apart.
Scene geometry stays within 150 m of its sensor (checked by the scene builder) and rays stop at
the maximum range, so no ray can reach a neighbouring cell. A sample's cell is fixed by its
index in the split (``index mod 4096``), not by its place in the batch, so the float32
coordinates Embree sees, and therefore which triangle each ray hits, do not depend on the batch
size. The distance to the hit is then recomputed in float64 in the sample's local frame.

Before building the Embree scene, triangles that no ray can hit first are dropped (exactly, no
approximation): faces of closed solids turned away from every laser origin, and triangles wholly
outside the horizontal wedge of the window. That keeps Embree's per-triangle setup cost down.
"""

from dataclasses import dataclass
from functools import cache

import numpy as np

from simlidar.scene.build import CELL_HALF_EXTENT_M, SceneBatch

GRID_CELLS = 16  # per axis
CELL_SPACING_M = 256.0  # > 2 x CELL_HALF_EXTENT_M - max range: neighbours stay out of reach
MAX_BATCH = GRID_CELLS**3
_WEDGE_MARGIN_M = 0.05  # covers the millimetre shift of laser origins under pitch


@dataclass(frozen=True)
class Hits:
    """What each pulse of B windows hits first."""

    range_m: np.ndarray  # (B, 16, W) float64, NaN where nothing is hit
    surface: np.ndarray  # (B, 16, W) uint8, 0 where nothing is hit
    on_object: np.ndarray  # (B, 16, W) bool, the hit belongs to the labelled object


@cache
def _device():
    import embreex.rtcore as rtc

    return rtc.EmbreeDevice()


def cell_offsets(slots: np.ndarray) -> np.ndarray:
    """World offset of each grid cell: (B,) int in [0, MAX_BATCH) -> (B, 3) float64."""
    ijk = np.stack([slots % GRID_CELLS, slots // GRID_CELLS % GRID_CELLS,
                    slots // GRID_CELLS**2], axis=-1)  # fmt: skip
    return (ijk - GRID_CELLS // 2) * CELL_SPACING_M


def visible_triangles(scene: SceneBatch, origins: np.ndarray, directions: np.ndarray):
    """Mask (T,) of the triangles some ray of the batch could hit first (see module doc)."""
    tris = scene.triangles
    # Back faces of closed solids. The origins of a window lie on one short segment (the
    # lasers' vertical offsets), so a face turned away from both ends is turned away from all.
    flat = origins.reshape(-1, 3)
    ends = flat[[np.argmin(flat[:, 2]), np.argmax(flat[:, 2])]]  # (2, 3)
    normal = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    facing = np.einsum("tk,etk->et", normal, ends[:, None, :] - tris[None, :, 0])  # (2, T)
    keep = ~(scene.closed & (facing <= 0).all(axis=0)) & (np.abs(normal).sum(axis=1) > 0)
    # The horizontal wedge spanned by the rays (azimuth clockwise from +x).
    azimuth = np.arctan2(-directions[..., 1], directions[..., 0])
    for bound, sign in ((azimuth.min(), 1.0), (azimuth.max(), -1.0)):
        edge = np.array([np.cos(bound), -np.sin(bound)])
        side = sign * (edge[0] * tris[..., 1] - edge[1] * tris[..., 0])  # (T, 3) > 0: outside
        keep &= ~(side > _WEDGE_MARGIN_M).all(axis=1)
    return keep


def cast(scene: SceneBatch, origins: np.ndarray, directions: np.ndarray, slots: np.ndarray,
         max_range_m: float, cull: bool = True) -> Hits:  # fmt: skip
    """First hit of every pulse.

    origins, directions : (B, 16, W, 3) float64 in each sample's local frame, unit directions
    slots : (B,) int, distinct grid cells (use the sample index in its split mod MAX_BATCH)
    cull : drop triangles no ray can hit first (exact; off only to test that it is)
    """
    import embreex.mesh_construction as mc
    import embreex.rtcore_scene as rtcs

    batch = origins.shape[0]
    if batch > MAX_BATCH or len(np.unique(slots)) != batch:
        raise ValueError(f"need {batch} distinct slots below {MAX_BATCH}, got {slots!r}")
    if max_range_m + CELL_HALF_EXTENT_M >= CELL_SPACING_M:
        raise ValueError(f"max range {max_range_m} m would reach the neighbouring cells")
    if cull:
        keep = np.nonzero(visible_triangles(scene, origins, directions))[0]
    else:
        keep = np.arange(len(scene.triangles))
    tris = scene.triangles[keep]
    sample = scene.sample[keep]
    offsets = cell_offsets(np.asarray(slots))  # (B, 3)

    shape = origins.shape[:-1]
    hit_range = np.full(shape, np.nan)
    surface = np.zeros(shape, np.uint8)
    on_object = np.zeros(shape, bool)
    if len(tris) == 0:
        return Hits(hit_range, surface, on_object)

    embree_scene = rtcs.EmbreeScene(_device())
    world = (tris + offsets[sample][:, None, :]).astype(np.float32)
    mc.TriangleMesh(embree_scene, world)
    ray_origin = (origins + offsets[:, None, None, :]).reshape(-1, 3).astype(np.float32)
    ray_dir = directions.reshape(-1, 3).astype(np.float32)
    far = np.full(len(ray_origin), max_range_m + 1.0, np.float32)
    prim = embree_scene.run(ray_origin, ray_dir, dists=far, output=1)["primID"].reshape(shape)

    hit = prim >= 0
    prim_hit = prim[hit]
    rows = np.nonzero(hit)[0]
    if (sample[prim_hit] != rows).any():
        raise RuntimeError("a ray hit another sample's scene: the cell isolation is broken")
    # Exact distance in float64: the ray's parameter where it meets the hit triangle's plane.
    t = tris[prim_hit]
    o, d = origins[hit], directions[hit]
    n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    hit_range[hit] = np.einsum("ij,ij->i", n, t[:, 0] - o) / np.einsum("ij,ij->i", n, d)
    surface[hit] = scene.surface[keep][prim_hit]
    on_object[hit] = scene.is_object[keep][prim_hit]
    return Hits(hit_range, surface, on_object)
