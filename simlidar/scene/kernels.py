"""The compiled (numba) kernel of scene building: every copy of a primitive's template scaled,
turned and moved in one pass, written where the batch's triangles go.

:func:`simlidar.scene.build.instance_triangles` does the same with one batched matrix product
per primitive (numpy's ``@``, a BLAS product) and :func:`simlidar.scene.build.build_batch` then
joins the pieces. The kernel gives the same numbers, bit for bit, because it repeats the
product's order of operations: a vertex ``v`` of the template becomes
``fma(vz, m2, fma(vy, m1, fma(vx, m0, 0))) + at`` per coordinate, ``m`` the coordinate's row of
``Rz(yaw) diag(size)`` with its zero entries (each term fused into the running sum:
:mod:`simlidar.fused`). That order was found by measurement on this project's machines (x86-64
with AVX-512, numpy 2.4 on OpenBLAS's SkylakeX kernels): the same products one operation at a
time round about 3 % of a turned cylinder's or arch's coordinates differently (a box's corners,
halves and ones, have exact products either way). ``tests/scene/test_build_kernels.py``
compares the two forms bit for bit wherever it runs, so a BLAS that orders otherwise fails
there rather than making a dataset's bytes depend on its size. The cosines and sines of the
yaws stay numpy's (its SIMD ``cos`` and the C library's may differ).
"""

from numba import njit

from simlidar.fused import fma


@njit(cache=True, nogil=True, error_model="numpy")
def _row(vx, vy, vz, m0, m1, m2):
    """One coordinate of a product's row, summed as BLAS sums it."""
    return fma(vz, m2, fma(vy, m1, fma(vx, m0, 0.0)))


@njit(cache=True, nogil=True, error_model="numpy")
def place_copies(template, cos_yaw, sin_yaw, size, at, limit, out):
    """Write the triangles of M copies of a template into ``out``; say whether they all lie
    within ``limit`` of the origin.

    template : (T, 3, 3) float64, the unit template's triangles
    cos_yaw, sin_yaw : (M,) float64, of each copy's counter-clockwise yaw
    size, at : (M, 3) float64, each copy's extent along x, y, z before yaw and bottom centre
    limit : every coordinate must be finite and at most this far from 0 (m)
    out : (M T, 3, 3) float64, copy m's triangles at rows m T .. (m + 1) T - 1
    returns : True when every coordinate written is within ``limit`` (NaN is not)
    """
    copies, count = size.shape[0], template.shape[0]
    inside = True
    for m in range(copies):
        c, s = cos_yaw[m], sin_yaw[m]
        m00, m01 = c * size[m, 0], -s * size[m, 1]
        m10, m11 = s * size[m, 0], c * size[m, 1]
        m22 = size[m, 2]
        ax, ay, az = at[m, 0], at[m, 1], at[m, 2]
        for t in range(count):
            row = m * count + t
            for v in range(3):
                vx, vy, vz = template[t, v, 0], template[t, v, 1], template[t, v, 2]
                x = _row(vx, vy, vz, m00, m01, 0.0) + ax
                y = _row(vx, vy, vz, m10, m11, 0.0) + ay
                z = _row(vx, vy, vz, 0.0, 0.0, m22) + az
                out[row, v, 0], out[row, v, 1], out[row, v, 2] = x, y, z
                if not (abs(x) <= limit and abs(y) <= limit and abs(z) <= limit):
                    inside = False
    return inside
