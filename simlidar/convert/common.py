"""What the converters share: delays from times, the seeded train/test choice, split attributes.

A converted split holds the same kind of values as a generated one: ``delays`` in [0, 1], the
arrival time of the first pulse (or spike) of a cell as a fraction of a listening window, and
1.0 where nothing arrived inside the window (``simlidar.generator.pulses.NO_RETURN``).
"""

import numpy as np

from simlidar.generator.pulses import NO_RETURN

# The largest float32 below 1.0: a pulse inside the window never rounds up to "no return".
_LAST_BEFORE_END = np.nextafter(np.float32(NO_RETURN), np.float32(0.0))


def delays_from_times(times: np.ndarray, window: float) -> np.ndarray:
    """Arrival times -> normalised delays ``times / window`` as float32.

    times : (...) float, in the unit of ``window``; NaN = nothing arrived
    returns : (...) float32 in [0, 1); NaN and times at or past the window are 1.0
    """
    times = np.asarray(times, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        inside = times < window  # NaN compares False
    fraction = np.where(inside, times / window, NO_RETURN).astype(np.float32)
    return np.where(inside, np.minimum(fraction, _LAST_BEFORE_END), np.float32(NO_RETURN))


def n_test_groups(n: int, test_fraction: float) -> int:
    """How many of ``n`` groups go to the test split: ``test_fraction * n`` rounded half up,
    kept within 1 .. n - 1 so that both splits get at least one group (n >= 2)."""
    return min(max(int(np.floor(test_fraction * n + 0.5)), 1), n - 1)


def choose_test(n: int, test_fraction: float, rng: np.random.Generator) -> np.ndarray:
    """A seeded choice of test groups: (n,) bool, True for the ``n_test_groups(n, ...)`` chosen."""
    chosen = np.zeros(n, dtype=bool)
    chosen[rng.permutation(n)[: n_test_groups(n, test_fraction)]] = True
    return chosen


def stream(seed: int, *key: int) -> np.random.Generator:
    """The random stream of ``seed`` for ``key`` (numpy SeedSequence child, as the generator)."""
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence(seed, spawn_key=key)))
