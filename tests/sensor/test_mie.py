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
    """The extinction paradox (van de Hulst 1957): Q_ext -> 2 as x grows (within 0.02 at
    x = 2000, nearer at 8000)."""
    q_ext, _, _ = efficiencies(np.array([2000.0, 8000.0]), 1.328 + 4.86e-7j)
    assert abs(q_ext[1] - 2.0) < abs(q_ext[0] - 2.0) < 0.02


def test_shapes_and_refusals():
    q = efficiencies(np.ones((2, 3)), 1.33)
    assert all(a.shape == (2, 3) for a in q)
    with pytest.raises(ValueError, match="size parameters"):
        efficiencies(np.array([0.0]), 1.33)
    with pytest.raises(ValueError, match="expected n \\+ i k"):
        efficiencies(np.array([1.0]), 1.33 - 0.1j)
    assert math.isfinite(float(efficiencies(np.array([1e-3]), 1.33)[2][0]))


# Wiscombe's MIEV0 test output (ilopushenko/miev0_matlab_interface@b4e1b23f, wiscombe/
# MVTstNew.out, cases 9-11, water m = 1.33 - 1e-5 i in MIEV0's sign convention, + here): Q_ext,
# Q_sca and 4 |S1(180)|^2 / x^2 (Q_back) from its S1(180 deg); Hong Du (2004, Appl. Opt. 43,
# Table 1) lists the same Q_ext and Q_sca
WISCOMBE = [
    (1.0, 0.093952, 0.093923, complex(2.24362e-02, 1.43711e-01)),
    (100.0, 2.101321, 2.096594, complex(-5.65921e01, 4.65097e01)),
    (10000.0, 2.004089, 1.723857, complex(-1.82119e02, -9.51912e02)),
]


@pytest.mark.parametrize(("x", "q_ext", "q_sca", "s1"), WISCOMBE, ids=lambda v: str(v))
def test_water_spheres_match_wiscombes_table(x, q_ext, q_sca, s1):
    got_ext, got_sca, got_back = efficiencies(np.array([x]), 1.33 + 1e-5j)
    assert got_ext[0] == pytest.approx(q_ext, abs=1.5e-6)
    assert got_sca[0] == pytest.approx(q_sca, abs=1.5e-6)
    assert got_back[0] == pytest.approx(4 * abs(s1) ** 2 / x**2, rel=2e-5)


def test_bohren_and_huffmans_appendix_sphere():
    """Bohren & Huffman's BHMIE example: m = 1.55, radius 0.525 um at 0.6328 um: Q_ext = Q_sca
    = 3.10543, Q_back = 2.92534 (as miepython's test_03_bh_dielectric and LISA's test quote
    it)."""
    x = 2 * math.pi * 0.525 / 0.6328
    q_ext, q_sca, q_back = efficiencies(np.array([x]), 1.55)
    assert q_ext[0] == pytest.approx(3.10543, abs=6e-6)
    assert q_sca[0] == pytest.approx(3.10543, abs=6e-6)
    assert q_back[0] == pytest.approx(2.92534, abs=6e-6)
