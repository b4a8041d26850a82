"""Beam footprints, waveforms and return modes (simlidar/sensor/footprint.py, waveform.py),
checked against what is derived by hand: a tilted plane's echo, a hand-made edge's two echoes
and the VLP-16 manual's rule for which two a dual-return pulse reports."""

import math

import numpy as np
import pytest

from simlidar.sensor.footprint import footprint, subray_count, subray_directions
from simlidar.sensor.receiver import load_receiver, received_power_w
from simlidar.sensor.waveform import BIN_NS, echoes, pulse_sigma_ns, reported, waveform

C_M_PER_NS = 0.299792458
RECEIVER = load_receiver("vlp16")
SIGMA = pulse_sigma_ns(RECEIVER.pulse_width_ns)


def test_the_rings_hold_helios_sub_ray_counts_and_weights_that_sum_to_one():
    assert [subray_count(q) for q in (1, 2, 3, 4)] == [1, 7, 19, 37]
    for rings in (1, 2, 3, 5):
        offsets, weights = footprint(rings)
        assert offsets.shape == (subray_count(rings), 2) and weights.shape == (len(offsets),)
        assert offsets[0].tolist() == [0.0, 0.0] and math.isclose(weights.sum(), 1.0)
        radius = np.hypot(*offsets.T)
        assert radius.max() < 1.0  # every sub-ray inside the 1/e^2 contour
        if rings > 1:  # the outer cells end at the contour: ring Q-1 at (Q-1) / (Q-1/2)
            assert math.isclose(radius.max(), (rings - 1) / (rings - 0.5))
            assert weights[0] > weights[-1]  # a Gaussian profile: the axis carries the most
    assert footprint(1)[1].tolist() == [1.0]
    with pytest.raises(ValueError, match="rings=0: expected an integer in"):
        footprint(0)


def test_sub_rays_keep_the_axis_and_spread_over_the_divergence():
    elevation, azimuth = math.radians(-7.0), math.radians(12.0)
    axis = np.array([math.cos(elevation) * math.cos(azimuth),
                     math.cos(elevation) * math.sin(azimuth), math.sin(elevation)])  # fmt: skip
    rays, weights = subray_directions(axis[None], 3.0, 1.5, 3)
    assert rays.shape == (1, 19, 3) and np.array_equal(rays[0, 0], axis)
    assert np.allclose(np.linalg.norm(rays, axis=-1), 1.0)
    off = np.arccos(np.clip(rays[0] @ axis, -1.0, 1.0))  # angle from the axis, rad
    # ring 2 at 2 / 2.5 of the half-angles (1.5 x 0.75 mrad): 1.2 mrad along the scan; ring 1
    # at 1 / 2.5, nearest the axis at phi = 60 degrees (its 6 rays: 0, 60, ... 300)
    assert math.isclose(off.max(), 0.8 * 1.5e-3, rel_tol=1e-6)
    nearest = 0.4e-3 * math.hypot(1.5 * math.cos(math.pi / 3), 0.75 * math.sin(math.pi / 3))
    assert math.isclose(off[1:].min(), nearest, rel_tol=1e-6)


def _plane_ranges(range_m, tilt_deg, rings):
    """Each sub-ray's range to a plane whose normal is ``tilt_deg`` from the beam's axis (+x)
    and which the axis meets at ``range_m``; the sub-rays' weights."""
    rays, weights = subray_directions(np.array([[1.0, 0.0, 0.0]]), 3.0, 1.5, rings)
    tilt = math.radians(tilt_deg)
    normal = np.array([-math.cos(tilt), -math.sin(tilt), 0.0])  # tilted along the scan
    point = np.array([range_m, 0.0, 0.0])
    return (normal @ point) / (rays[0] @ normal), weights, tilt


def test_a_tilted_plane_echoes_at_2r_over_c_widened_by_its_range_spread():
    """The echo of a plane that fills the beam: its peak at 2R/c and its width the pulse's,
    sigma^2 = sigma_pulse^2 + the power-weighted variance of the sub-rays' times (a sum of
    close Gaussians), the full width at half maximum read off the sampled waveform."""
    range_m, rho = 20.0, 0.3
    for tilt_deg in (0.0, 60.0, 80.0):
        ranges, weights, tilt = _plane_ranges(range_m, tilt_deg, rings=4)
        power = received_power_w(RECEIVER, ranges, rho, tilt) * weights
        times = 2.0 * ranges / C_M_PER_NS
        echo = echoes(times[None], power[None], SIGMA)
        assert echo.count.tolist() == [1]
        assert abs(echo.time_ns[0, 0] - 2.0 * range_m / C_M_PER_NS) < 0.01  # 1.5 mm
        mean = (power * times).sum() / power.sum()
        spread = (power * (times - mean) ** 2).sum() / power.sum()
        by_hand = 2.0 * math.sqrt(2.0 * math.log(2.0) * (SIGMA**2 + spread))
        t = np.arange(times.min() - 10.0, times.max() + 10.0, 0.001)
        wave = waveform(times, power, SIGMA, t)
        above = t[wave >= wave.max() / 2.0]
        assert math.isclose(above[-1] - above[0], by_hand, rel_tol=0.01), tilt_deg
        assert math.isclose(echo.power_w[0, 0], wave.max(), rel_tol=1e-3)
        if tilt_deg == 80.0:  # up to 17 cm of range across the footprint: 2.4 % wider
            assert by_hand > 1.02 * RECEIVER.pulse_width_ns
        if tilt_deg == 0.0:  # a plane square to the beam: the range equation's power
            assert math.isclose(wave.max(), received_power_w(RECEIVER, range_m, rho), rel_tol=1e-3)


def test_one_sub_ray_gives_the_rays_own_time_and_power():
    times = np.array([[133.4], [np.nan], [20.01]])
    power = np.array([[2e-7], [0.0], [5e-6]])
    echo = echoes(times, power, SIGMA)
    assert echo.count.tolist() == [1, 0, 1]
    assert np.allclose(echo.time_ns[[0, 2], 0], [133.4, 20.01], rtol=0, atol=1e-9)
    assert np.allclose(echo.power_w[[0, 2], 0], [2e-7, 5e-6], rtol=1e-9)
    assert np.isnan(echo.time_ns[1]).all()


def _edge(near_w, far_w, near_m=10.0, far_m=15.0, sub=6):
    """A hand-made edge: half a beam's sub-rays on a surface at ``near_m``, half on one at
    ``far_m``, with these powers in all."""
    times = np.r_[np.full(sub, 2 * near_m / C_M_PER_NS), np.full(sub, 2 * far_m / C_M_PER_NS)]
    power = np.r_[np.full(sub, near_w / sub), np.full(sub, far_w / sub)]
    return times, power


def _returns_m(mode, *pulses):
    times, power = zip(*pulses)
    echo = echoes(np.stack(times), np.stack(power), SIGMA)
    pick = reported(echo, RECEIVER.threshold_w, mode, RECEIVER.dual_when_strongest_is_last)
    t = np.where(pick >= 0, np.take_along_axis(echo.time_ns, np.maximum(pick, 0), 1), np.nan)
    return np.round(t * C_M_PER_NS / 2.0, 3).tolist()


def test_an_edge_gives_two_echoes_and_the_modes_follow_the_manual():
    t = RECEIVER.threshold_w
    near_strong = _edge(40 * t, 10 * t)  # the strongest is the first
    far_strong = _edge(10 * t, 40 * t)  # the strongest is the last: dual adds the second
    three = (np.r_[_edge(10 * t, 40 * t)[0], 2 * 12.0 / C_M_PER_NS],
             np.r_[_edge(10 * t, 40 * t)[1], 20 * t])  # fmt: skip
    single = _edge(30 * t, 0.0)
    near_faint = _edge(0.5 * t, 40 * t)  # the near echo below the threshold: never reported
    pulses = (near_strong, far_strong, single, near_faint)
    assert _returns_m("strongest", *pulses) == [[10.0], [15.0], [10.0], [15.0]]
    assert _returns_m("last", *pulses) == [[15.0], [15.0], [10.0], [15.0]]
    assert _returns_m("dual", *pulses) == [[15.0, 10.0], [15.0, 10.0], [10.0, 10.0], [15.0, 15.0]]
    # three echoes, the last the strongest: dual adds the second strongest (12 m, not 10 m)
    assert _returns_m("dual", three) == [[15.0, 12.0]]
    echo = echoes(np.stack([far_strong[0]]), np.stack([far_strong[1]]), SIGMA)
    assert echo.count.tolist() == [2] and np.allclose(echo.power_w[0], [10 * t, 40 * t])


def test_echoes_closer_than_the_pulse_merge_into_one_between_them():
    """Two surfaces 0.3 m apart (2 ns, under the 5 ns pulse) give one echo between them, the
    mixed pixel of real sensors; 1.5 m apart (10 ns) they give two."""
    t = RECEIVER.threshold_w
    close = _edge(20 * t, 20 * t, near_m=10.0, far_m=10.3)
    apart = _edge(20 * t, 20 * t, near_m=10.0, far_m=11.5)
    echo = echoes(np.stack([close[0], apart[0]]), np.stack([close[1], apart[1]]), SIGMA)
    assert echo.count.tolist() == [1, 2]
    assert math.isclose(echo.time_ns[0, 0] * C_M_PER_NS / 2.0, 10.15, abs_tol=1e-3)
    assert echo.power_w[0, 0] > 20 * t  # the two pulses overlap: more than either alone


def test_the_waveform_is_sampled_at_helios_bin_size():
    assert BIN_NS == 0.25 and math.isclose(SIGMA, 5.0 / 2.3548200450309493)


def test_the_stored_waveform_samples_the_formula_near_every_echo():
    """sampled(): P(t) at every t = k bin within 4 sigma of an echo (the formula, by
    waveform(), less the tails of echoes farther than 4 sigma), 0 beyond 4 sigma and two bins;
    two echoes that overlap add."""
    from simlidar.sensor.waveform import REACH_SIGMAS, sampled, waveform

    sigma = pulse_sigma_ns(4.0)
    times = np.array([[133.4, np.nan], [66.7, 70.0], [np.nan, np.nan]])
    powers = np.array([[2e-7, 0.0], [1e-7, 5e-8], [0.0, 0.0]])
    got = sampled(times, powers, sigma, 0.5, 400)
    assert got.shape == (3, 400) and got.dtype == np.float32
    t = np.arange(400) * 0.5
    for p in range(3):
        expected = waveform(times[p], powers[p], sigma, t)
        hit = times[p][~np.isnan(times[p])]
        near = (np.abs(t[:, None] - hit[None, :]) <= REACH_SIGMAS * sigma).any(axis=1)
        # an echo's tail beyond its 4 sigma is left out: at most exp(-8) of its peak
        atol = math.exp(-(REACH_SIGMAS**2) / 2) * powers[p].max()
        np.testing.assert_allclose(got[p][near], expected[near], rtol=1e-6, atol=atol)
        far = ~(np.abs(t[:, None] - hit[None, :]) <= REACH_SIGMAS * sigma + 2 * 0.5).any(axis=1)
        assert (got[p][far] == 0).all()
    assert got[0].argmax() * 0.5 == pytest.approx(133.5)  # the bin nearest 2R/c of 20 m


def test_echoes_apart_are_found_on_their_own_windows_bit_for_bit():
    """Without fog, a pulse's waveform is evaluated around each run of its echoes, not across
    the gap between runs: the echoes are those of one window from the first echo to the last
    (the fog path's, with no fog), bit for bit, for sub-rays and extra columns alike."""
    from simlidar.sensor.weather import FogTable

    g = np.random.default_rng(3)
    pulses = 400
    times = np.where(g.random((pulses, 3)) < 0.7, g.uniform(10, 600, (pulses, 3)), np.nan)
    times[:, 1] = np.where(g.random(pulses) < 0.5, times[:, 0] + g.uniform(0, 12, pulses), np.nan)
    powers = 10 ** g.uniform(-9, -5, (pulses, 3))
    extra = np.where(g.random((pulses, 2)) < 0.3, g.uniform(10, 60, (pulses, 2)), np.nan)
    extra_w = 10 ** g.uniform(-9, -6, (pulses, 2))
    sigma = pulse_sigma_ns(4.0)
    apart = echoes(times, powers, sigma, BIN_NS, None, None, extra, extra_w)
    no_fog = FogTable(0, np.zeros((1, 1)), 0.0, BIN_NS)
    whole = echoes(times, powers, sigma, BIN_NS, no_fog, np.full(pulses, -1), extra, extra_w)
    assert apart.time_ns.shape[1] >= 3  # pulses with several runs of echoes
    np.testing.assert_array_equal(apart.time_ns, whole.time_ns)
    np.testing.assert_array_equal(apart.power_w, whole.power_w)
    np.testing.assert_array_equal(apart.count, whole.count)


def test_echoes_skip_only_terms_that_are_exactly_zero(monkeypatch):
    """Each echo's Gaussian is computed only within ZERO_SIGMAS of it (beyond, exp(x < -750)
    is 0.0 in float64) and no-hit padding not at all: the echoes are those of computing every
    term on every bin, bit for bit, for sub-rays, extra columns (drops) and fog alike."""
    import simlidar.sensor.waveform as waveform
    from simlidar.sensor.weather import FogTable

    assert math.exp(-0.5 * waveform.ZERO_SIGMAS**2) == 0.0
    g = np.random.default_rng(7)
    pulses = 300
    times = np.where(g.random((pulses, 3)) < 0.8, g.uniform(10, 600, (pulses, 3)), np.nan)
    powers = 10 ** g.uniform(-9, -5, (pulses, 3))
    extra = np.where(g.random((pulses, 4)) < 0.5, g.uniform(10, 600, (pulses, 4)), np.nan)
    extra_w = 10 ** g.uniform(-9, -6, (pulses, 4))
    sigma = pulse_sigma_ns(5.0)  # terms beyond 82 ns skipped: most pairs of echoes here
    fog = FogTable(0, g.uniform(0, 1e-8, (2400, 2)), 0.0, BIN_NS)
    columns = g.integers(-1, 2, pulses)
    for more in ((None, None), (fog, columns)):
        skipped = echoes(times, powers, sigma, BIN_NS, *more, extra, extra_w)
        with monkeypatch.context() as m:
            m.setattr(waveform, "ZERO_SIGMAS", math.inf)  # every term on every bin
            every = echoes(times, powers, sigma, BIN_NS, *more, extra, extra_w)
        np.testing.assert_array_equal(skipped.time_ns, every.time_ns)
        np.testing.assert_array_equal(skipped.power_w, every.power_w)
        np.testing.assert_array_equal(skipped.count, every.count)
