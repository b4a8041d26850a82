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
* Scan timing (``--timing scan``, :func:`scan_delays`): the delays above (noise included)
  become arrival times in the sweep, ``(emission_ns + d * tof_max_ns) / window_ns``; a pixel
  at 1.0 stays 1.0. Noise is timing jitter of the time of flight, so it keeps its size in ns.
"""

import numpy as np

from simlidar.dataset.schema import (
    MOTION_SCHEMA,
    RECEIVER_SCHEMA,
    RETURNS_SCHEMA,
    SCHEMA,
    WAVEFORM_SCHEMA,
)
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
    level, u : the noise level a and the pixels' uniforms in [0, 1) (as ``clean``): the
        noise is ``level * u``
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


def scan_delays(
    delays: np.ndarray, emission_ns: np.ndarray, tof_max_ns: float, window_ns: float
) -> np.ndarray:
    """Flash delays -> scan-timed delays: each pulse's arrival time in the sweep, emission plus
    ``delay * tof_max_ns``, divided by ``window_ns`` (the bound of
    :func:`simlidar.sensor.rays.scan_window_ns`, so a return stays inside (0, 1)). A delay of
    1.0 (no return under the physical rule, or noise pushed past the window) stays 1.0; under
    the paper profile a missing return (0.0 plus noise) arrives with its emission.

    delays : (B, H, W) float32; emission_ns : (B, H, W) float64
    returns : (B, H, W) float32
    """
    arrival = (emission_ns + delays.astype(np.float64) * tof_max_ns) / window_ns
    return np.where(delays < NO_RETURN, arrival, NO_RETURN).astype(np.float32)


def split_rows(samples, config) -> dict[str, np.ndarray]:
    """The rows of a generated split (:func:`simlidar.dataset.schema.generated_shapes`) from a
    block of simulated :class:`~simlidar.generator.simulate.Samples` and the dataset's
    :class:`~simlidar.generator.config.GeneratorConfig`: the profile's pulse rule and
    ``U(0, noise)`` noise applied to the clean delays (:func:`profile_pulses`;
    ``clean_delays`` are written under the rule too, before noise), under scan timing both
    made arrival times (:func:`scan_delays`) and the emission times stored; under a receiver
    its fields (:data:`~simlidar.dataset.schema.RECEIVER_SCHEMA`), and where returns come from
    waveforms theirs (:data:`~simlidar.dataset.schema.RETURNS_SCHEMA`), in motion the motions
    (:data:`~simlidar.dataset.schema.MOTION_SCHEMA`); every other field as
    simulated."""
    rule = config.pulse_rule
    clean, noisy = profile_pulses(
        samples.clean_delays,
        config.noise,
        samples.noise_u,
        rule["missing_delay"],
        rule["noise_on"],
    )
    rows = {"delays": noisy, "clean_delays": clean}
    if config.timing == "scan":
        window, tof_max = config.scan_window_ns, config.sensor.tof_max_ns
        rows = {n: scan_delays(d, samples.emission_ns, tof_max, window) for n, d in rows.items()}
        rows["emission_ns"] = samples.emission_ns
    if config.receiver is not None:
        rows |= {name: getattr(samples, name) for name in RECEIVER_SCHEMA}
    if config.reported_returns:
        rows |= {name: getattr(samples, name) for name in RETURNS_SCHEMA}
    if config.waveform_bins:
        rows |= {name: getattr(samples, name) for name in WAVEFORM_SCHEMA}
    if config.moves:
        rows |= {name: getattr(samples, name) for name in MOTION_SCHEMA}
    return rows | {name: getattr(samples, name) for name in SCHEMA if name not in rows}
