"""Detection statistics (issue 62, item 1): the false-alarm rate against Rice's formula on
band-limited Gaussian noise made here, the detection probability against the threshold's
Gaussian form and against draws, the alarms' count and height, the background by hand."""

import math

import numpy as np
import pytest

from simlidar.sensor.detection import (
    ELECTRON_CHARGE_C,
    Detector,
    background_w,
    detect,
    detection_probability,
    false_alarm_rate_hz,
    false_alarms,
    noise_w,
    snr_for_probability,
    threshold_for_rate,
)

DETECTOR = Detector(
    responsivity_a_w=0.5,
    excess_noise=4.0,
    bandwidth_hz=100e6,
    own_noise_w=1e-9,
    filter_nm=20.0,
    field_sr=1e-5,
)


def _band_limited_noise(samples: int, band: float, seed: int) -> np.ndarray:
    """Gaussian noise of a flat spectrum up to ``band`` (a fraction of the sampling rate), unit
    variance: white noise with every Fourier component above the band set to zero."""
    g = np.random.default_rng(seed)
    spectrum = np.fft.rfft(g.standard_normal(samples))
    spectrum[np.fft.rfftfreq(samples) > band] = 0.0
    noise = np.fft.irfft(spectrum, samples)
    return noise / noise.std()


@pytest.mark.parametrize("level", [2.0, 3.0])
def test_upward_crossings_of_filtered_noise_follow_rice(level):
    """Noise band-limited to B = f_s / 20 crosses T = 2 and 3 sigma upward (B / sqrt(3))
    exp(-T^2 / 2 sigma^2) times a second: the count of 2^21 samples within 4 Poisson sigmas."""
    samples, band = 2**21, 1.0 / 20.0
    noise = _band_limited_noise(samples, band, seed=int(level))
    up = np.count_nonzero((noise[:-1] < level) & (noise[1:] >= level))
    detector = Detector(0.5, 4.0, band, 1.0, 20.0, 1e-5)  # B in cycles a sample
    expected = float(false_alarm_rate_hz(detector, level, 1.0)) * samples
    assert expected > 300
    assert abs(up - expected) < 4.0 * math.sqrt(expected), (up, expected)


def test_alarm_peaks_exceed_the_threshold_by_sigma_squared_over_t():
    """The tops of filtered noise's excursions over T = 3.5 sigma lie above T by about sigma^2
    / T on average (the exponential of :func:`false_alarms`; asymptotic, so within 20 %), and
    false_alarms draws that mean."""
    noise = _band_limited_noise(2**22, 1.0 / 20.0, seed=7)
    level = 3.5
    over = noise >= level
    starts = np.flatnonzero(over[1:] & ~over[:-1]) + 1
    ends = np.flatnonzero(~over[1:] & over[:-1]) + 1
    ends = ends[ends > starts[0]]
    tops = np.array([noise[a:b].max() for a, b in zip(starts, ends, strict=False)])
    assert len(tops) > 100
    assert np.mean(tops - level) == pytest.approx(1.0 / level, rel=0.2)
    g = np.random.default_rng(0)
    _, _, peaks = false_alarms(g, 200_000, 1e6, 1e-6, level, 1.0)
    assert np.all(peaks >= level)
    assert np.mean(peaks - level) == pytest.approx(1.0 / level, rel=0.02)


def test_false_alarms_are_poisson_in_time_and_count():
    g = np.random.default_rng(1)
    pulses, rate, listen = 100_000, 3e5, 667e-9  # 0.2 alarms a pulse
    pulse, time_s, _ = false_alarms(g, pulses, rate, listen, 4.0, 1.0)
    mean = rate * listen
    assert len(pulse) == pytest.approx(mean * pulses, abs=4 * math.sqrt(mean * pulses))
    assert np.all(np.diff(pulse) >= 0) and np.all((time_s >= 0) & (time_s < listen))
    counts = np.bincount(pulse, minlength=pulses)
    assert np.mean(counts == 0) == pytest.approx(math.exp(-mean), abs=0.005)


def test_threshold_and_rate_invert_each_other():
    sigma = 2e-9
    for rate in (1.0, 1e3, 1e6):
        t = threshold_for_rate(DETECTOR, rate, sigma)
        assert float(false_alarm_rate_hz(DETECTOR, t, sigma)) == pytest.approx(rate, rel=1e-12)
    with pytest.raises(ValueError, match="expected a rate in"):
        threshold_for_rate(DETECTOR, DETECTOR.bandwidth_hz, sigma)


def test_detection_probability_is_mathworks_example():
    """MathWorks, "False Alarm Rate for CFAR Detectors": unit noise, threshold 3.0902 (P_fa
    1e-3 a sample), amplitude 4: P_d = 0.8185."""
    assert float(detection_probability(4.0, 3.0902, 1.0)) == pytest.approx(0.8185, abs=1e-4)
    assert float(detection_probability(0.0, 3.0902, 1.0)) == pytest.approx(1e-3, rel=1e-3)
    assert snr_for_probability(0.5, 5.0) == 5.0
    assert float(detection_probability(snr_for_probability(0.9, 5.0), 5.0, 1.0)) == pytest.approx(
        0.9
    )


@pytest.mark.parametrize("snr", [3.0, 4.0, 5.0, 6.0])
def test_drawn_detections_follow_the_probability(snr):
    g = np.random.default_rng(int(snr))
    draws = 200_000
    sigma = float(noise_w(DETECTOR, snr * 1e-9))
    _, seen = detect(g, np.full(draws, snr * 1e-9), 5e-9, sigma)
    p = float(detection_probability(snr * 1e-9, 5e-9, sigma))
    assert np.mean(seen) == pytest.approx(p, abs=4 * math.sqrt(p * (1 - p) / draws) + 1e-9)


def test_noise_adds_shot_noise_of_signal_and_background_by_hand():
    """sigma^2 = sigma_0^2 + 2 q F B (P + P_b) / R_0; P_b = E d_lambda rho / pi A_r Omega eta."""
    signal, back = 1e-7, 2e-8
    by_hand = math.sqrt(1e-18 + 2 * ELECTRON_CHARGE_C * 4.0 * 100e6 * (signal + back) / 0.5)
    assert float(noise_w(DETECTOR, signal, back)) == pytest.approx(by_hand, rel=1e-12)
    p_b = float(background_w(DETECTOR, 0.7, 0.3, 3.1416e-4, 0.05))
    assert p_b == pytest.approx(0.7 * 20.0 * 0.3 / math.pi * 3.1416e-4 * 1e-5 * 0.05, rel=1e-12)
    assert float(background_w(DETECTOR, 0.0, 0.3, 3.1416e-4, 0.05)) == 0.0


def test_a_detector_is_checked():
    with pytest.raises(ValueError, match="bandwidth_hz=0"):
        Detector(0.5, 4.0, 0, 1e-9, 20.0, 1e-5)
    with pytest.raises(ValueError, match="excess_noise=0.5"):
        Detector(0.5, 0.5, 1e8, 1e-9, 20.0, 1e-5)
