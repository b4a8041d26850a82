"""Rain (simlidar/sensor/weather.py, after LISA): the extinction coefficient against the
Marshall-Palmer integral and a published curve, a drop's echo against the range equation, the
restricted drop sampler against LISA's brute-force sampling of every drop in the beam, and the
drops it leaves out against the threshold."""

import math

import numpy as np
import pytest
from scipy.integrate import quad

import simlidar.sensor.weather as weather
from simlidar.sensor.receiver import load_receiver, received_power_w

RECEIVER = load_receiver("vlp16")
C = weather.C_M_PER_NS


def _rain(rate_mm_h, receiver=RECEIVER):
    return weather.rain(
        receiver.peak_power_w, receiver.aperture_area_m2, receiver.optics_efficiency,
        receiver.threshold_w, receiver.divergence_h_mrad, receiver.divergence_v_mrad, rate_mm_h,
    )  # fmt: skip


def _size_distribution(rate_mm_h):
    """N(D) per m^3 and mm (Marshall-Palmer), D in mm."""
    slope = 4.1 * rate_mm_h**-0.21
    return lambda d: 8000.0 * math.exp(-slope * d)


@pytest.mark.parametrize("rate", [1.0, 10.0, 50.0, 200.0])
def test_the_extinction_is_the_marshall_palmer_integral(rate):
    """alpha = (pi / 4) 1e-6 int D^2 Q_ext N(D) dD, Q_ext = 2, by quad."""
    n = _size_distribution(rate)
    by_hand = math.pi / 4 * 1e-6 * 2.0 * quad(lambda d: d**2 * n(d), 0, 60, limit=200)[0]
    assert weather.rain_extinction_per_m(rate) == pytest.approx(by_hand, rel=1e-9)
    assert weather.rain_extinction_per_m(0.0) == 0.0


def test_the_extinction_follows_ulbrich_and_atlas():
    """Ulbrich & Atlas's fit for rain at 905 nm, k = 1.45 R^0.64 dB/km (their eq. 8, the curve
    LISA draws beside its own in python_old/mie_plots.py), over its 1-20 mm/h: within 10 %."""
    for rate in (1.0, 2.0, 5.0, 10.0, 20.0):
        ours_db_per_km = 10.0 * math.log10(math.e) * weather.rain_extinction_per_m(rate) * 1e3
        assert ours_db_per_km / (1.45 * rate**0.64) == pytest.approx(1.0, abs=0.10)
    # 10 mm/h: 1.56e-3 per m (the figure the docs quote)
    assert weather.rain_extinction_per_m(10.0) == pytest.approx(1.556e-3, rel=1e-3)


def test_a_drops_echo_is_the_range_equation_for_its_share_of_the_beam():
    drops = _rain(10.0)
    water = ((1.328 - 1) / (1.328 + 1)) ** 2
    assert weather.fresnel_reflectance(1.328) == pytest.approx(water)
    solid = RECEIVER.divergence_h_mrad * RECEIVER.divergence_v_mrad * 1e-6
    for r, d_mm in [(3.0, 1.0), (9.0, 2.0), (20.0, 4.0)]:
        share = (d_mm * 1e-3) ** 2 / (solid * r**2)  # under 1 here
        assert share < 1
        alpha = weather.rain_extinction_per_m(10.0)
        target = received_power_w(RECEIVER, r, water * share, 0.0, alpha)
        expected = target * float(weather.crossover(r))
        assert drops.echo_w(r, d_mm, alpha) == pytest.approx(expected, rel=1e-12)
    # a drop larger than the beam is a target that fills it; none before the crossover
    near = weather.CROSSOVER_M[1] + 0.1  # fully seen
    big = 1e3 * math.sqrt(solid) * near * 2  # mm: twice the beam's width there
    assert drops.echo_w(near, big, 0.0) == pytest.approx(
        received_power_w(RECEIVER, near, water, 0.0, 0.0)
    )
    assert drops.echo_w(1.0, 5.0, 0.0) == 0.0


def _bound(drops, range_m, diameter_mm):
    """A drop's echo without the cap, the crossover and extinction (each at most 1)."""
    return drops.full_w * (diameter_mm * 1e-3) ** 2 / (drops.solid_angle * range_m**4)


@pytest.mark.parametrize("rate", [5.0, 50.0])
def test_the_sampler_draws_what_lisa_draws_where_a_drop_can_be_seen(rate):
    """LISA (lisa_mc) draws every drop over 0.05 mm in the beam's cone, N_tot V of them,
    diameters 0.05 mm + Exp(Lambda), ranges uniform in the cone's volume. Among those, the
    drops whose echo could reach RAIN_FLOOR x the threshold beyond r_1 must come as often and
    with the same diameters and ranges as the sampler's."""
    drops = _rain(rate)
    g = np.random.default_rng(7)
    beams = 20000
    r_max = 14.0  # the brute force's cone: it holds every drop the sampler draws up to
    largest = (r_max / drops.reach_m) ** 2  # this diameter (6.1 mm), the two compared below it
    slope = weather.rain_slope_per_mm(rate)
    d_st = 0.05
    per_m3 = 8000.0 * math.exp(-slope * d_st) / slope
    volume = math.pi / 12 * drops.solid_angle * r_max**3
    count = g.poisson(per_m3 * volume * beams)
    d = d_st + g.exponential(1 / slope, count)
    r = r_max * np.cbrt(g.random(count))
    seen = (_bound(drops, r, d) >= weather.RAIN_FLOOR * RECEIVER.threshold_w) & (
        r > weather.CROSSOVER_M[0]
    )
    seen &= d < largest
    lisa_d, lisa_r = d[seen], r[seen]

    pulse, r_ours, d_ours = drops.draw(np.random.default_rng(8), beams)
    inside = (r_ours > weather.CROSSOVER_M[0]) & (d_ours < largest)
    assert drops.smallest_mm > d_st  # smaller drops are never seen
    assert np.all(_bound(drops, r_ours, d_ours) >= weather.RAIN_FLOOR * RECEIVER.threshold_w)
    ours_d, ours_r = d_ours[inside], r_ours[inside]
    # counts: Poisson, so within 5 sigma of each other
    spread = math.sqrt(len(lisa_d) + len(ours_d))
    assert abs(len(ours_d) - len(lisa_d)) < 5 * spread
    assert len(lisa_d) > 500
    # the distributions: means and quartiles within a few standard errors
    for ours, theirs in ((ours_d, lisa_d), (ours_r, lisa_r)):
        error = math.sqrt(theirs.var() / len(theirs) + ours.var() / len(ours))
        assert abs(ours.mean() - theirs.mean()) < 5 * error
        assert np.quantile(ours, [0.25, 0.5, 0.75]) == pytest.approx(
            np.quantile(theirs, [0.25, 0.5, 0.75]), rel=0.05
        )
    assert np.array_equal(np.sort(pulse), pulse)  # in pulse order, as _drop_echoes reads them


def test_the_drops_left_out_sum_to_far_below_the_threshold():
    """The mean summed echo of the drops the sampler leaves out (their echo under RAIN_FLOOR x
    the threshold even at their bound), in a slab of the pulse's full width at half maximum at
    any range: under 2 % of the threshold, at 200 mm/h (the mean scales with the rate)."""
    drops = _rain(200.0)
    n = _size_distribution(200.0)
    slab_m = RECEIVER.pulse_width_ns * C / 2
    floor = weather.RAIN_FLOOR * RECEIVER.threshold_w

    def left_out_w(r):
        # drops of D < D_max(r), where the bound reaches the floor: (r / reach)^2 mm
        largest = (r / drops.reach_m) ** 2
        area = math.pi / 4 * drops.solid_angle * r**2
        echo = lambda d: n(d) * area * _bound(drops, r, d) * float(weather.crossover(r))  # noqa: E731
        return slab_m * quad(echo, 0, largest, limit=200)[0]

    worst = max(left_out_w(r) for r in np.linspace(weather.CROSSOVER_M[0], 60.0, 300))
    assert 0 < worst < 0.02 * RECEIVER.threshold_w
    assert worst < floor


def test_no_rain_is_no_drops_and_the_mean_grows_with_the_rate():
    assert _rain(0.0) is None
    means = [_rain(r).mean_per_pulse for r in (1.0, 10.0, 100.0)]
    assert means == sorted(means) and means[0] > 0
    # a 1 mm drop is seen (at the floor) up to reach = (K rho_w 1e-6 / (Omega 0.1 P_th))^(1/4)
    full_w = 80 * 3.1416e-4 * 0.05 * ((1.328 - 1) / (1.328 + 1)) ** 2 / math.pi
    by_hand = (full_w * 1e-6 / (3e-3 * 1.5e-3 * 0.1 * RECEIVER.threshold_w)) ** 0.25
    assert _rain(10.0).reach_m == pytest.approx(by_hand, rel=1e-4)
