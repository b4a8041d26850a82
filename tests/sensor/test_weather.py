"""Fog's backscatter (simlidar/sensor/weather.py), against what is derived by hand: the
crossover ranges of Hahner et al.'s biaxial geometry, the tabulated fog waveform against a
numerical integral of the soft-target equation, a beam blocked by a surface, and the echoes a
pulse then has in each return mode."""

import math

import numpy as np
import pytest
from scipy.integrate import quad

import simlidar.sensor.weather as weather
from simlidar.sensor.receiver import koschmieder_extinction_per_m, load_receiver
from simlidar.sensor.waveform import BIN_NS, echoes, pulse_sigma_ns, reported

RECEIVER = load_receiver("vlp16")
SIGMA = pulse_sigma_ns(RECEIVER.pulse_width_ns)
C = weather.C_M_PER_NS


def _table(visibility_m, max_range_m=100.0, crossover_m=None):
    return weather.fog_table(
        RECEIVER.peak_power_w, RECEIVER.aperture_area_m2, RECEIVER.optics_efficiency,
        RECEIVER.threshold_w, visibility_m, koschmieder_extinction_per_m(visibility_m),
        SIGMA, BIN_NS, max_range_m, None, crossover_m or weather.CROSSOVER_M,
    )  # fmt: skip


def _by_hand(t_ns, visibility_m, blocked_m=math.inf):
    """P_0 A_r eta beta int g(t - 2R/c) xi(R) exp(-2 alpha R) / R^2 dR, by quad."""
    alpha = koschmieder_extinction_per_m(visibility_m)
    beta = 0.046 / visibility_m
    constant = RECEIVER.peak_power_w * RECEIVER.aperture_area_m2 * RECEIVER.optics_efficiency

    def integrand(r):
        shape = math.exp(-((t_ns - 2 * r / C) ** 2) / (2 * SIGMA**2))
        return shape * float(weather.crossover(r)) * math.exp(-2 * alpha * r) / r**2

    centre = t_ns * C / 2
    low, high = weather.CROSSOVER_M[0], min(blocked_m, centre + 2.0)
    if high <= low:
        return 0.0
    return constant * beta * quad(integrand, low, high, points=[centre], limit=200)[0]


def test_the_crossover_is_hahners_biaxial_geometry():
    """R_1 = (D - rho_T - rho_R) / (tan(g_T/2) + tan(g_R/2)) = 0.08 / (0.017455 + 0.030553),
    R_2 = (D - rho_R + rho_T) / (tan(g_R/2) - tan(g_T/2)) = 0.1 / 0.013098."""
    low, high = weather.CROSSOVER_M
    assert low == pytest.approx(0.08 / (math.tan(math.radians(1.0)) + math.tan(math.radians(1.75))))
    assert (round(low, 3), round(high, 3)) == (1.666, 7.635)
    xi = weather.crossover([1.0, low, (low + high) / 2, high, 20.0])
    assert xi == pytest.approx([0.0, 0.0, 0.5, 1.0, 1.0], abs=1e-12)
    assert weather.backscatter_per_m_sr(50.0) == pytest.approx(0.046 / 50)


@pytest.mark.parametrize("visibility_m", [200.0, 20.0])
def test_the_fog_waveform_is_the_soft_target_integral(visibility_m):
    table = _table(visibility_m)
    assert table is not None
    for distance in (2.0, 4.0, 7.0, 12.0):
        k = round(2 * distance / C / BIN_NS)
        row = k - table.first_bin
        expected = _by_hand(k * BIN_NS, visibility_m)
        assert table.watts[row, -1] == pytest.approx(expected, rel=0.01), distance
    # blocked at 5 m: the fog up to it, and nothing a few sigma beyond
    j = table.column(np.array([5.0]))[0]
    k = round(2 * 4.5 / C / BIN_NS)
    assert table.watts[k - table.first_bin, j] == pytest.approx(
        _by_hand(k * BIN_NS, visibility_m, 5.0), rel=0.02
    )
    far = round((2 * 5.0 / C + 5 * SIGMA) / BIN_NS) - table.first_bin
    assert table.watts[far, j] < 1e-4 * table.watts[far, -1]
    assert table.column(np.array([0.5, np.nan]))[0] == -1  # nearer than the crossover: no fog
    assert table.column(np.array([np.nan]))[0] == table.watts.shape[1] - 1


def test_thin_fog_is_too_faint_to_tabulate():
    assert _table(1e6) is None


def test_the_fogs_echo_joins_the_modes():
    """With Hahner et al.'s slider crossover (0.9 to 1.0 m) fog of 50 m visibility echoes near
    1.3 m (the 5 ns pulse), stronger than a dark surface at 20 m: strongest reports the fog,
    last the surface, dual both; with Hahner et al.'s default geometry (1.67 to 7.64 m) and
    their backscatter 0.046 / V the fog's echo stays under the threshold and the surface is
    all a pulse reports."""
    t_hard = 2 * 20.0 / C
    hard_w = 5 * RECEIVER.threshold_w
    for crossover, expected in (
        ((0.9, 1.0), {"strongest": [1.3], "last": [20.0], "dual": [20.0, 1.3]}),
        (weather.CROSSOVER_M, {"strongest": [20.0], "last": [20.0], "dual": [20.0, 20.0]}),
    ):
        table = _table(50.0, crossover_m=crossover)
        columns = table.column(np.array([20.0]))
        echo = echoes(np.array([[t_hard]]), np.array([[hard_w]]), SIGMA, BIN_NS, table, columns)
        for mode, ranges in expected.items():
            pick = reported(echo, RECEIVER.threshold_w, mode)[0]
            got = [round(float(echo.time_ns[0, i]) * C / 2, 1) for i in pick]
            assert got == ranges, (crossover, mode)


def test_a_stored_waveform_holds_the_fog_under_the_surfaces_echo():
    """sampled() with fog: the surfaces' samples plus the fog table's column at every bin the
    table covers (its bins fall on the stored ones), and a pulse without fog (column -1)
    unchanged; where no surface echoes, the fog alone."""
    from simlidar.sensor.waveform import sampled

    table = _table(20.0)
    times = np.array([[2 * 20.0 / C], [2 * 20.0 / C], [np.nan]])
    powers = np.full((3, 1), 5 * RECEIVER.threshold_w)
    columns = np.array([table.column(np.array([20.0]))[0], -1, table.column(np.array([np.nan]))[0]])
    bare = sampled(times, powers, SIGMA, 1.0, 700)
    foggy = sampled(times, powers, SIGMA, 1.0, 700, table, columns)
    np.testing.assert_array_equal(foggy[1], bare[1])
    k = np.arange(700)
    row = 4 * k - table.first_bin
    inside = (row >= 0) & (row < len(table.watts))
    for p in (0, 2):
        fog = np.zeros(700)
        fog[inside] = table.watts[row[inside], columns[p]]
        np.testing.assert_allclose(foggy[p], (bare[p] + fog).astype(np.float32), rtol=1e-6)
        assert fog.max() > 0.1 * RECEIVER.threshold_w  # fog of 20 m: 0.6 of the threshold
