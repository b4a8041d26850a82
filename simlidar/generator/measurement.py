"""The receiver's measurement of its echoes (issue 62): each peak with the detector's noise, the
noise's own false alarms, the reflectivity byte of the measured signal, and the fog's Mie
backscatter, for :mod:`simlidar.generator.returns` (its single-ray and waveform paths draw the
same noise in the same order: the measurement, the false alarms, then the range noise).
The physics: :mod:`simlidar.sensor.detection`; docs/sensor-model.md, "The calibrated receiver".
"""

import numpy as np

from simlidar.sensor.model import SPEED_OF_LIGHT_M_PER_S, Sensor, tof_ns
from simlidar.sensor.receiver import (
    Receiver,
    apparent_reflectance,
    reflectivity_byte,
    signal_noise_w,
)


def measure_peaks(receiver: Receiver, streams, power_w, rho):
    """Peak powers as the receiver measures them: ``power_w`` (n, H, W, E) plus the noise of
    :func:`simlidar.sensor.receiver.signal_noise_w` (over the sunlight a scene of ``rho``
    sends) times a standard normal, E a pulse from each sample's stream (drawn whatever the
    powers, so a sample's draws never depend on its block). Without noise, the powers and no
    draw."""
    if receiver.noise_w == 0.0:
        return power_w
    sigma = signal_noise_w(receiver, power_w, rho)
    z = np.stack([g.standard_normal(power_w.shape[1:]) for g in streams])
    return power_w + sigma * z


def false_alarm_echoes(receiver: Receiver, streams, sensor: Sensor, rho):
    """The strongest false alarm of each pulse (range m, peak W; NaN / 0: none): the noise
    crossing the threshold while the pulse listens for 2 R_max / c, at Rice's rate for the
    noise without signal (:mod:`simlidar.sensor.detection`), drawn from each sample's stream
    (a Poisson count a pulse, then two uniforms an alarm). None without noise."""
    from simlidar.sensor.detection import false_alarm_rate_hz, false_alarms

    shape = rho.shape
    if receiver.noise_w == 0.0 or not receiver.bandwidth_hz > 0.0:
        return np.full(shape, np.nan), np.zeros(shape)
    listen_s = 2.0 * sensor.max_range_m / SPEED_OF_LIGHT_M_PER_S
    detector = receiver.detector()
    quiet = signal_noise_w(receiver, np.zeros(shape), rho)  # sigma_n, the pulse's background
    rate = false_alarm_rate_hz(detector, receiver.threshold_w, quiet)
    range_m, peak_w = np.full(shape, np.nan), np.zeros(shape)
    pixels = int(np.prod(shape[1:]))
    for i, g in enumerate(streams):
        pulse, time_s, height = false_alarms(
            g, pixels, rate[i].ravel(), listen_s, receiver.threshold_w, quiet[i].ravel()
        )
        strongest = np.zeros(pixels)
        np.maximum.at(strongest, pulse, height)
        keep = height == strongest[pulse]
        r, w = np.full(pixels, np.nan), np.zeros(pixels)
        r[pulse[keep]] = time_s[keep] * SPEED_OF_LIGHT_M_PER_S / 2.0
        w[pulse[keep]] = height[keep]
        range_m[i], peak_w[i] = r.reshape(shape[1:]), w.reshape(shape[1:])
    return range_m, peak_w


def reflectivity(receiver: Receiver, peak_w, range_m, retroreflective):
    """The reflectivity byte of returns of measured peak ``peak_w`` at ``range_m``: the
    apparent reflectance (range-compensated, :func:`simlidar.sensor.receiver.apparent_reflectance`)
    on the sensor's scale, a retro-reflector's (and any echo brighter than a white diffuse
    target) on its retro-reflective range."""
    apparent = apparent_reflectance(receiver, np.maximum(peak_w, 0.0), range_m)
    return reflectivity_byte(receiver, apparent, retroreflective | (apparent > 1.0))


ECHOES_MEASURED = 4  # a pulse's strongest echoes measured with noise (see measured_echoes)


def fog_backscatter(visibility_m: float, wavelength_nm: float) -> float:
    """beta (1 / (m sr)) of the fog of visibility V at the receiver's wavelength: Mie theory
    over the shipped fog's drops (:func:`simlidar.sensor.scattering.fog_coefficients`)."""
    from simlidar.sensor.scattering import fog_coefficients

    return fog_coefficients(visibility_m, wavelength_nm).backscatter_per_m_sr


def measured_echoes(receiver: Receiver, streams, sensor: Sensor, echo, rho, pixels_shape):
    """The echoes of a block of pulses as the receiver measures them: each pulse's
    ``ECHOES_MEASURED`` strongest peaks plus noise (:func:`measure_peaks`: that many standard
    normals a pulse, so a sample's draws do not depend on its block; a further echo of a pulse,
    weaker than four others, keeps its noiseless peak), and the pulse's strongest false alarm
    (:func:`false_alarm_echoes`) as one more echo. Without noise, ``echo`` itself.

    receiver, streams : the receiver and each sample's receiver stream (n samples)
    sensor : whose maximum range sets how long a pulse listens for false alarms
    echo : the block's :class:`simlidar.sensor.waveform.Echoes` (P = n x H x W pulses)
    rho : (P,) the scene's rho f(theta) behind each pulse, for the sunlight's noise
    pixels_shape : (H, W), a sample's pulses
    """
    if receiver.noise_w == 0.0:
        return echo
    n = len(streams)
    power = np.nan_to_num(echo.power_w, nan=-np.inf)
    order = np.argsort(-power, axis=1, kind="stable")[:, :ECHOES_MEASURED]
    top = np.take_along_axis(power, order, axis=1)
    top = np.pad(top, ((0, 0), (0, ECHOES_MEASURED - top.shape[1])), constant_values=-np.inf)
    alive = np.isfinite(top)
    shape = (n, *pixels_shape, ECHOES_MEASURED)
    measured = measure_peaks(
        receiver, streams, np.where(alive, top, 0.0).reshape(shape),
        np.broadcast_to(rho.reshape(n, *pixels_shape)[..., None], shape),
    )  # fmt: skip
    measured = measured.reshape(-1, ECHOES_MEASURED)
    new_power = echo.power_w.copy()
    rows = np.arange(len(power))[:, None]
    columns = order.shape[1]
    new_power[rows, order] = np.where(alive[:, :columns], measured[:, :columns], np.nan)
    alarm_m, alarm_w = false_alarm_echoes(receiver, streams, sensor, rho.reshape(n, *pixels_shape))
    alarm_ns, alarm_w = tof_ns(alarm_m.ravel()), alarm_w.ravel()
    times = np.hstack([echo.time_ns, alarm_ns[:, None]])
    powers = np.hstack([new_power, np.where(np.isnan(alarm_ns), np.nan, alarm_w)[:, None]])
    # each pulse's echoes in time order again, NaN last
    key = np.where(np.isnan(times), np.inf, times)
    again = np.argsort(key, axis=1, kind="stable")
    times = np.take_along_axis(times, again, axis=1)
    powers = np.take_along_axis(powers, again, axis=1)
    return type(echo)(times, powers, (~np.isnan(times)).sum(axis=1))
