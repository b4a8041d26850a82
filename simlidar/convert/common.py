"""What the converters share: delays from times, the seeded train/test choice, split attributes.

A converted split holds the same kind of values as a generated one: ``delays`` in [0, 1], the
arrival time of the first pulse (or spike) of a cell as a fraction of a listening window, and
1.0 where nothing arrived inside the window (``simlidar.generator.pulses.NO_RETURN``).
"""

import json

import h5py
import numpy as np

from simlidar import __version__
from simlidar.dataset.version import SOURCES
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


def converted_split_attrs(
    source: str,
    split: str,
    config,
    class_names: tuple[str, ...],
    class_mode: str,
    sensor: dict,
    input_sha256: str,
) -> dict:
    """The attributes every converted split carries (``docs/converters.md``); a converter adds
    its own (``tof_max_ns``, ``time_window_us``, ...).

    source : the converter's source (``kitti``, ``dvs-barrel``), a key of
        :data:`simlidar.dataset.version.SOURCES`, which gives the dataset version
    split : ``train`` or ``test``
    config : the converter's configuration (:class:`~simlidar.convert.config.KittiConfig`,
        :class:`~simlidar.convert.config.DvsConfig`), stored as JSON with its seed
    class_names : the class names, in label order
    class_mode : what a class is (``object``, ``character``)
    sensor : what recorded the data (its name, resolution, range or time unit), stored as JSON
    input_sha256 : sha256 of the input (of what, per source: ``docs/converters.md``)
    """
    strings = h5py.string_dtype()
    return {
        "dataset_version": SOURCES[source][0],
        "simlidar_version": __version__,
        "source": source,
        "split": split,
        "config": config.to_json(),
        "seed": config.seed,
        "noise": 0.0,
        "classes": len(class_names),
        "class_mode": class_mode,
        "class_names": np.array(class_names, dtype=strings),
        "sensor": json.dumps(sensor, sort_keys=True),
        "no_return_delay": NO_RETURN,
        "input_sha256": input_sha256,
    }
