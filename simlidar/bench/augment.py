"""The training rows' noise drawn anew each epoch (``noise_augment``), from the train split's
clean delays, on the sensor's clock for scan-timed data."""

import numpy as np

from simlidar.dataset.loaders import load_split
from simlidar.errors import ConfigError
from simlidar.generator.pulses import noisy_delays, scan_delays


def fresh_noise(dataset, attrs: dict, seed: int, rows: np.ndarray):
    """``noise_augment``: a function drawing the train split's noise anew (same level, same
    profile rule, from ``clean_delays``) for each epoch, (len(rows), H, W) float32 delays: the
    paper's "adding noise randomly" as augmentation rather than one fixed draw per sample, for
    the training ``rows`` (the validation rows keep the file's draw, like the test split).
    Seeded by the training seed. The early-information estimate draws the same way. Under scan
    timing the noise is drawn on each pulse's time of flight, as the generator draws it, and the
    draw made arrival times again (before issue 42 it was added to the arrival times: a jitter
    of ``noise`` times the whole 9.5 ms window)."""
    if "source" in attrs or "noise" not in attrs:
        raise ConfigError(
            f"{dataset}: training option noise_augment: expected a generated dataset "
            "(clean_delays and a noise level), got converted data"
        )
    clean = load_split(dataset, "train", field="clean_delays")[0][rows]
    level = float(attrs["noise"])
    missing = float(attrs.get("no_return_delay", 1.0))
    noise_on = attrs.get("noise_on", "returns")
    rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence(seed, spawn_key=(7,))))
    timed = scan_clock(dataset, attrs, rows)
    if timed is not None:  # the noise is on the time of flight, then the sweep's clock
        clean = flash_delays(clean, *timed)

    def draw() -> np.ndarray:
        u = rng.random(clean.shape, dtype=np.float32)
        noisy = noisy_delays(clean, level, u, missing, noise_on)
        return noisy if timed is None else scan_delays(noisy, *timed)

    return draw


def scan_clock(dataset, attrs: dict, rows: np.ndarray):
    """A scan-timed train split's (emission_ns of ``rows``, tof_max_ns, window_ns), the
    arguments of :func:`simlidar.generator.pulses.scan_delays`; None under flash timing."""
    if attrs.get("timing") != "scan":
        return None
    emission = load_split(dataset, "train", field="emission_ns")[0][rows]
    return emission, float(attrs["tof_max_ns"]), float(attrs["delay_unit_ns"])


def flash_delays(arrival: np.ndarray, emission_ns, tof_max_ns: float, window_ns: float):
    """Scan-timed delays -> the flash delays they were made from (the inverse of
    :func:`simlidar.generator.pulses.scan_delays`, to within the float32 rounding of an
    arrival time: 4e-4 of ``tof_max_ns`` for a 9.5 ms window); 1.0 (no return) stays 1.0."""
    tof = (arrival.astype(np.float64) * window_ns - emission_ns) / tof_max_ns
    below_one = np.nextafter(np.float32(1.0), np.float32(0.0))
    return np.where(arrival < 1.0, np.clip(tof, 0.0, below_one), 1.0).astype(np.float32)
