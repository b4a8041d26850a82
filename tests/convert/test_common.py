"""The pieces both converters share: delays from arrival times, the seeded split by group."""

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from simlidar.convert.common import choose_test, delays_from_times, n_test_groups, stream


def test_delays_from_times_by_hand():
    window = 100.0
    times = np.array([0.0, 50.0, 100.0, 150.0, np.nan, 100.0 - 1e-9])
    delays = delays_from_times(times, window)
    assert delays.dtype == np.float32
    assert delays[:5].tolist() == [0.0, 0.5, 1.0, 1.0, 1.0]
    assert delays[5] < 1.0  # a pulse inside the window never reads as "no return"


@given(
    st.lists(st.one_of(st.floats(0, 1e6), st.just(float("nan"))), max_size=50),
    st.floats(1e-3, 1e6),
)
def test_delays_are_in_range_and_one_only_outside_the_window(times, window):
    times = np.array(times, dtype=float)
    delays = delays_from_times(times, window)
    assert ((delays >= 0) & (delays <= 1)).all()
    outside = np.isnan(times) | (times >= window)
    np.testing.assert_array_equal(delays == 1.0, outside)


@given(st.integers(2, 10_000), st.floats(0.001, 0.999))
def test_both_splits_get_a_group(n, fraction):
    assert 1 <= n_test_groups(n, fraction) <= n - 1


def test_the_test_count_rounds_half_up_and_the_choice_is_seeded():
    assert [n_test_groups(3, 0.2), n_test_groups(10, 0.25), n_test_groups(2, 0.5)] == [1, 3, 1]
    first = choose_test(10, 0.3, stream(7, 1))
    assert first.sum() == 3 and (first == choose_test(10, 0.3, stream(7, 1))).all()
    assert any((choose_test(10, 0.3, stream(s, 1)) != first).any() for s in range(8, 12))
