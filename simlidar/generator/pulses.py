"""Hits -> pulses: range quantisation, range limits, time of flight, delays, noise.

Conventions (``docs/sensor-model.md`` explains them):

* A return exists where a surface is hit within ``[min_range_m, max_range_m)`` after rounding
  the range to the sensor's 2 mm resolution; its round-trip time of flight is ``2 r / c``. The
  maximum range itself is excluded so that a return's delay stays below 1.0 (no return).
* Normalised delay ``d = tof / tof(max_range)``, in (0, 1) for a return. **No return is 1.0**:
  the end of the listening window, where a pulse that never comes back is still unseen.
* Noise: ``noisy = min(d + a * u, 1)`` with ``u ~ U(0, 1)`` drawn for every pulse of every
  sample (so noise is ``U(0, a)``). Noise only delays; clipping at 1.0 happens here and only
  here, so a pulse pushed past the window reads exactly like no return, and a no-return pulse
  stays 1.0.
* Optional delay-shift augmentation (the paper's): every return of a sample moves by the same
  ``s``; a return shifted out of (0, 1) becomes no return. Applied before noise.
* A dataset profile (``simlidar.generator.profiles``) may write a missing return as 0.0
  instead and put the noise on every pixel (:func:`profile_pulses`); the physical profile is
  the rule above.
"""

import numpy as np

from simlidar.dataset.schema import SCHEMA
from simlidar.sensor.model import Sensor, tof_ns

NO_RETURN = 1.0


def quantise_range(range_m: np.ndarray, sensor: Sensor) -> np.ndarray:
    """Round ranges to the sensor's resolution; NaN (no return) outside [min, max)."""
    r = np.round(range_m / sensor.range_resolution_m) * sensor.range_resolution_m
    inside = (r >= sensor.min_range_m) & (r < sensor.max_range_m)  # NaN compares False
    return np.where(inside, r, np.nan)


def delays_from_range(range_m: np.ndarray, sensor: Sensor):
    """Quantised range -> (tof_ns float64 with NaN for no return, clean delay float32)."""
    tof = tof_ns(range_m)
    delay = np.where(np.isnan(tof), NO_RETURN, tof / sensor.tof_max_ns)
    return tof, delay.astype(np.float32)


def shift_delays(delay: np.ndarray, shift: np.ndarray) -> np.ndarray:
    """Move every return of each sample by ``shift`` (B,); out-of-window returns vanish.

    delay : (B, ...) float32 clean delays
    """
    s = np.asarray(shift, dtype=np.float32).reshape((-1,) + (1,) * (delay.ndim - 1))
    moved = delay + s
    keep = (delay < NO_RETURN) & (moved > 0.0) & (moved < NO_RETURN)
    return np.where(keep, moved, np.float32(NO_RETURN)).astype(np.float32)


def add_noise(delay: np.ndarray, level: float, u: np.ndarray) -> np.ndarray:
    """Uniform noise U(0, level) on every pulse, clipped at 1.0 (the only clipping)."""
    noisy = delay + np.float32(level) * u.astype(np.float32)
    return np.minimum(noisy, np.float32(NO_RETURN)).astype(np.float32)


def profile_pulses(
    clean: np.ndarray, level: float, u: np.ndarray, missing_delay: float, noise_on: str
) -> tuple[np.ndarray, np.ndarray]:
    """Clean delays (missing return = 1.0) -> (clean, noisy) delays under a profile's rule.

    clean : (..., H, W) float32, returns in (0, 1), missing returns at NO_RETURN
    missing_delay : 0.0 or 1.0, what a missing return is written as
    noise_on : "returns" (noise delays returns only) or "all" (every pixel)
    returns : clean delays with missing returns at ``missing_delay``, and those with
        ``U(0, level)`` noise added where ``noise_on`` says, clipped at 1.0. For the physical
        rule (1.0, "returns") the noisy delays are exactly :func:`add_noise`'s.
    """
    written = (
        clean
        if missing_delay == NO_RETURN
        else np.where(clean < NO_RETURN, clean, np.float32(missing_delay)).astype(np.float32)
    )
    return written, noisy_delays(written, level, u, missing_delay, noise_on)


def noisy_delays(
    clean: np.ndarray, level: float, u: np.ndarray, missing_delay: float, noise_on: str
) -> np.ndarray:
    """A profile's clean delays (missing at ``missing_delay``) plus ``level * u`` where
    ``noise_on`` says, clipped at 1.0. Returns lie strictly inside (0, 1), so a pixel equal to
    ``missing_delay`` (0.0 or 1.0) is a missing return. Also used to draw fresh noise in
    training (``noise_augment``)."""
    noisy = add_noise(clean, level, u)
    if noise_on == "returns" and missing_delay != NO_RETURN:  # (1.0 stays 1.0 by clipping)
        noisy = np.where(clean == np.float32(missing_delay), clean, noisy).astype(np.float32)
    return noisy


def split_rows(samples, level: float, rule: dict) -> dict[str, np.ndarray]:
    """The rows of a generated split (:data:`simlidar.dataset.schema.SCHEMA`) from a block of
    simulated :class:`~simlidar.generator.simulate.Samples`: the profile's ``rule``
    (``GeneratorConfig.pulse_rule``) and ``U(0, level)`` noise applied to the clean delays
    (:func:`profile_pulses`; ``clean_delays`` are written under the rule too, before noise),
    every other field as simulated."""
    clean, noisy = profile_pulses(
        samples.clean_delays, level, samples.noise_u, rule["missing_delay"], rule["noise_on"]
    )
    rows = {"delays": noisy, "clean_delays": clean}
    return rows | {name: getattr(samples, name) for name in SCHEMA if name not in rows}
