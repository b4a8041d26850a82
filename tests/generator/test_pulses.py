import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from simlidar.generator.pulses import (
    NO_RETURN,
    add_noise,
    delays_from_range,
    quantise_range,
    shift_delays,
)
from simlidar.sensor import default_sensor

ranges = arrays(np.float64, (4, 16, 16), elements=st.one_of(st.floats(0.0, 150.0), st.just(np.nan)))


def test_ranges_are_quantised_to_2_mm_and_limited():
    r = quantise_range(
        np.array([0.5, 1.0, 10.0009, 10.0011, 99.9979, 99.999, 100.2, np.nan]), default_sensor()
    )
    np.testing.assert_allclose(r[1:5], [1.0, 10.0, 10.002, 99.998])
    # 99.999 m rounds to the maximum range, which is excluded: a return's delay stays < 1
    assert np.isnan(r[[0, 5, 6, 7]]).all()


@settings(max_examples=40, deadline=None)
@given(r=ranges, level=st.floats(0.0, 1.0), seed=st.integers(0, 2**32 - 1))
def test_delays_lie_in_0_1_and_noise_only_delays(r, level, seed):
    sensor = default_sensor()
    tof, clean = delays_from_range(quantise_range(r, sensor), sensor)
    u = np.random.default_rng(seed).random(r.shape, dtype=np.float32)
    noisy = add_noise(clean, level, u)
    for d in (clean, noisy):
        assert d.dtype == np.float32
        assert ((d >= 0) & (d <= 1)).all()
    assert (noisy >= clean).all()
    assert (noisy - clean <= np.float32(level) + 1e-6).all()
    # no return stays exactly 1.0, and only it or a clipped pulse reads 1.0
    assert (noisy[np.isnan(tof)] == NO_RETURN).all()
    assert (clean[~np.isnan(tof)] < NO_RETURN).all()


def test_noise_is_uniform_on_0_a():
    clean = np.full((200_000,), 0.2, np.float32)
    u = np.random.default_rng(0).random(clean.shape, dtype=np.float32)
    noise = add_noise(clean, 0.33, u) - clean
    assert 0.0 <= noise.min() < 0.001 and 0.329 < noise.max() <= 0.33 + 1e-6
    assert abs(noise.mean() - 0.165) < 0.002  # mean of U(0, 0.33)


def test_a_shift_moves_returns_and_drops_what_leaves_the_window():
    clean = np.array([[0.1, 0.5, 0.95, NO_RETURN]], np.float32)
    np.testing.assert_allclose(shift_delays(clean, [0.1])[0], [0.2, 0.6, NO_RETURN, NO_RETURN])
    np.testing.assert_allclose(shift_delays(clean, [-0.2])[0], [NO_RETURN, 0.3, 0.75, NO_RETURN])
