from fractions import Fraction

from numba import njit

from simlidar.fused import fma


def test_fma_rounds_once():
    fused = njit(lambda x, y, z: fma(x, y, z))
    x, y, z = 1 + 2.0**-30, 1 - 2.0**-30, -1.0  # x y = 1 - 2^-60 exactly
    assert x * y + z == 0.0  # rounded twice
    assert fused(x, y, z) == float(Fraction(x) * Fraction(y) + Fraction(z)) == -(2.0**-60)
