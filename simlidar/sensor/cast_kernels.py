"""Compiled (numba) kernels of the batched ray cast: the rays, culling, packing, the exact range.

Each kernel does in one pass over its rows what :mod:`simlidar.sensor.raycast` (and
:func:`simlidar.sensor.rays.window_rays`) do with a dozen numpy calls (temporaries, gathers,
casts): the same numbers, bit for bit, because each one repeats numpy's own order of
operations. The orders were found by measurement on this project's machines (x86-64 with
AVX-512; numpy 2.4's SIMD loops, OpenBLAS's SkylakeX kernels), and
``tests/sensor/test_cast_kernels.py`` compares the two forms bit for bit (whole datasets
included) wherever it runs, so a numpy or BLAS that orders otherwise fails there rather than
making a dataset's bytes depend on its size:

* a three-term ``np.einsum("ij,ij->i", a, b)`` sums ``0 + ((a0 b0 + a2 b2) + a1 b1)`` (numpy
  pairs the lanes of a SIMD register, 0 with 2, then 1, from zeroed accumulators);
* ``normals @ ends.T`` (a BLAS product) is ``fma(a2, b2, fma(a1, b1, fma(a0, b0, 0)))``: each
  term fused into the running sum (:func:`simlidar.fused.fma`, LLVM's ``llvm.fma``, exact on
  every CPU). Its result is only compared with a plane's offset (which side of a face a laser
  origin lies on); a BLAS built without fused products would round some of these differently,
  changing the side only where an origin lies in a face's plane to the last bit, where no ray
  can hit the face;
* everything else is one operation at a time, in float64, rounded to float32 where numpy cast
  (``astype``, an assignment into a float32 array): LLVM fuses nothing here (no ``fastmath``).

Division by zero gives inf or NaN as numpy's does (``error_model="numpy"``), not an exception.
"""

import numpy as np
from numba import njit

from simlidar.fused import fma


@njit(cache=True, nogil=True, error_model="numpy")
def _dot3(ax, ay, az, bx, by, bz):
    """numpy's three-term ``einsum`` dot product, in its order (from a zeroed accumulator: an
    exact zero is +0, never -0)."""
    return 0.0 + ((ax * bx + az * bz) + ay * by)


@njit(cache=True, nogil=True)
def rays(cos_start, sin_start, cos_firing, sin_firing, cos_elevation, sin_elevation, row_origins):
    """The origins and directions of :func:`simlidar.sensor.rays.window_rays` (and of
    ``sweep_rays``) from the cosines and sines numpy computed, one pass (the products are
    numpy's, one operation at a time).

    cos_start, sin_start : (B, W) float64, of each column's cycle start (radians)
    cos_firing, sin_firing : (H,) float64, of each row's firing offset
    cos_elevation, sin_elevation : (H,) float64, of each row's laser elevation
    row_origins : (H, 3) float64, each row's emitter
    returns : origins, directions (B, H, W, 3) float64 (untilted: the pitch is applied after)
    """
    batch, width = cos_start.shape
    height = cos_firing.shape[0]
    origins = np.empty((batch, height, width, 3))
    directions = np.empty((batch, height, width, 3))
    for b in range(batch):
        for h in range(height):
            for w in range(width):
                cos_a = cos_start[b, w] * cos_firing[h] - sin_start[b, w] * sin_firing[h]
                sin_a = sin_start[b, w] * cos_firing[h] + cos_start[b, w] * sin_firing[h]
                directions[b, h, w, 0] = cos_elevation[h] * cos_a
                directions[b, h, w, 1] = -cos_elevation[h] * sin_a  # clockwise azimuth
                directions[b, h, w, 2] = sin_elevation[h]
                for c in range(3):
                    origins[b, h, w, c] = row_origins[h, c]
    return origins, directions


@njit(cache=True, nogil=True, error_model="numpy")
def cull(triangles, closed, ends):
    """The culling pass of :func:`simlidar.sensor.raycast.visible_triangles`.

    triangles : (T, 3, 3) float64
    closed : (T,) bool, the triangle is a face of a closed solid with outward winding
    ends : (2, 3) float64, the two ends of the window's segment of laser origins
    returns : keep (T,) bool, normal (T, 3) float64 (unnormalised, e1 x e2), plane (T,) float64
        (``normal . vertex0``)
    """
    count = triangles.shape[0]
    normal = np.empty((count, 3))
    plane = np.empty(count)
    keep = np.empty(count, np.bool_)
    for t in range(count):
        ax, ay, az = triangles[t, 0, 0], triangles[t, 0, 1], triangles[t, 0, 2]
        e1x, e1y, e1z = triangles[t, 1, 0] - ax, triangles[t, 1, 1] - ay, triangles[t, 1, 2] - az
        e2x, e2y, e2z = triangles[t, 2, 0] - ax, triangles[t, 2, 1] - ay, triangles[t, 2, 2] - az
        nx = e1y * e2z - e1z * e2y
        ny = e1z * e2x - e1x * e2z
        nz = e1x * e2y - e1y * e2x
        p = _dot3(nx, ny, nz, ax, ay, az)
        normal[t, 0], normal[t, 1], normal[t, 2] = nx, ny, nz
        plane[t] = p
        back = closed[t]
        for j in range(2):
            if back:
                dot = fma(nz, ends[j, 2], fma(ny, ends[j, 1], fma(nx, ends[j, 0], 0.0)))
                back = dot - p <= 0.0  # NaN: not a back face, as numpy's comparison says
        keep[t] = not back and (nx != 0.0 or ny != 0.0 or nz != 0.0)
    return keep, normal, plane


@njit(cache=True, nogil=True)
def pack_vertices(triangles, keep, sample, offsets):
    """The kept triangles moved into their samples' grid cells, as Embree reads them.

    triangles : (T, 3, 3) float64 in each sample's local frame
    keep : (K,) int, the triangles to pack, in order
    sample : (T,) int, each triangle's sample in the batch
    offsets : (B, 3) float64, each sample's cell offset
    returns : (3 K, 4) float32, one 16-byte row a vertex (the fourth column 0), each coordinate
        ``float32(local + offset)``
    """
    count = keep.shape[0]
    vertices = np.zeros((3 * count, 4), np.float32)
    for i in range(count):
        t = keep[i]
        s = sample[t]
        for v in range(3):
            for c in range(3):
                vertices[3 * i + v, c] = np.float32(triangles[t, v, c] + offsets[s, c])
    return vertices


@njit(cache=True, nogil=True)
def ray_origins(origins, offsets):
    """(B, R, 3) float64 origins in each sample's local frame, (B, 3) cell offsets -> (B R, 3)
    float32 world origins, ``float32(local + offset)``."""
    batch, rays = origins.shape[0], origins.shape[1]
    out = np.empty((batch * rays, 3), np.float32)
    for b in range(batch):
        for r in range(rays):
            for c in range(3):
                out[b * rays + r, c] = np.float32(origins[b, r, c] + offsets[b, c])
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def first_hits(prim, keep, normal, plane, origins, directions, sample, surface, is_object):
    """Each ray's hit, from Embree's primitive ids: the exact float64 range and its triangle's
    tags.

    prim : (B R,) int32, the hit's index among the packed triangles, -1 where none
    keep : (K,) int, the packed triangles' indices in the batch
    normal, plane : (T, 3) and (T,) float64, from :func:`cull`
    origins, directions : (B, R, 3) float64 in each sample's local frame
    sample, surface, is_object : (T,) the triangles' sample, surface id and object flag
    returns : range (B R,) float64 (NaN: no hit; where the ray meets the hit triangle's plane),
        surface (B R,) uint8, on_object (B R,) bool, cos (B R,) float32 (|cos| of the incidence
        angle, 0: no hit), and whether every ray hit its own sample's scene
    """
    batch, rays = origins.shape[0], origins.shape[1]
    out_range = np.full(batch * rays, np.nan)
    out_surface = np.zeros(batch * rays, np.uint8)
    out_object = np.zeros(batch * rays, np.bool_)
    out_cos = np.zeros(batch * rays, np.float32)
    isolated = True
    for b in range(batch):
        for r in range(rays):
            i = b * rays + r
            if prim[i] < 0:
                continue
            k = keep[prim[i]]
            if sample[k] != b:
                isolated = False
            nx, ny, nz = normal[k, 0], normal[k, 1], normal[k, 2]
            d, o = directions[b, r], origins[b, r]
            n_dot_d = _dot3(nx, ny, nz, d[0], d[1], d[2])
            n_dot_o = _dot3(nx, ny, nz, o[0], o[1], o[2])
            out_range[i] = (plane[k] - n_dot_o) / n_dot_d
            out_surface[i] = surface[k]
            out_object[i] = is_object[k]
            out_cos[i] = np.float32(np.abs(n_dot_d) / np.sqrt(_dot3(nx, ny, nz, nx, ny, nz)))
    return out_range, out_surface, out_object, out_cos, isolated
