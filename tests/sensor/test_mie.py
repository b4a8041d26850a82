"""Mie efficiencies of spheres (issue 62, item 5): the series against its limits and a
published table; the committed tables of water and what fog and rain make of them."""

import math

import numpy as np
import pytest

from simlidar.sensor.mie import efficiencies


def _rayleigh(m: complex) -> float:
    return abs((m**2 - 1) / (m**2 + 2)) ** 2


@pytest.mark.parametrize("m", [1.33 + 0j, 1.5 + 0.1j, 1.328 + 4.86e-7j])
def test_small_spheres_follow_rayleigh(m):
    """x = 0.01: Q_sca = (8/3) x^4 K and Q_back = 4 x^4 K, K = |(m^2 - 1) / (m^2 + 2)|^2
    (Bohren & Huffman eqs. 5.8 and 4.82 in the small-particle limit), to O(x^2)."""
    x = 0.01
    _, q_sca, q_back = efficiencies(np.array([x]), m)
    assert q_sca[0] == pytest.approx(8 / 3 * x**4 * _rayleigh(m), rel=1e-3)
    assert q_back[0] == pytest.approx(4 * x**4 * _rayleigh(m), rel=1e-3)


def test_a_sphere_that_does_not_absorb_scatters_all_it_takes():
    q_ext, q_sca, _ = efficiencies(np.geomspace(0.1, 500, 40), 1.33 + 0j)
    np.testing.assert_allclose(q_sca, q_ext, rtol=1e-9)


def test_large_spheres_take_twice_their_shadow():
    """The extinction paradox (van de Hulst 1957): Q_ext -> 2 as x grows."""
    q_ext, _, _ = efficiencies(np.array([5000.0, 20000.0]), 1.328 + 4.86e-7j)
    np.testing.assert_allclose(q_ext, 2.0, atol=0.01)


def test_shapes_and_refusals():
    q = efficiencies(np.ones((2, 3)), 1.33)
    assert all(a.shape == (2, 3) for a in q)
    with pytest.raises(ValueError, match="size parameters"):
        efficiencies(np.array([0.0]), 1.33)
    with pytest.raises(ValueError, match="expected n \\+ i k"):
        efficiencies(np.array([1.0]), 1.33 - 0.1j)
    assert math.isfinite(float(efficiencies(np.array([1e-3]), 1.33)[2][0]))
