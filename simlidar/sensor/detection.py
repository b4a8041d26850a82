"""Detection as a probability: a received pulse is signal plus noise (issue 62, item 1).

The receiver's output, referred to the optical power at its input, carries Gaussian noise of
variance (an avalanche photodiode's noise; the APD user guide of PerkinElmer/Excelitas, eq. 3,
with the amplifier's Johnson noise added as an independent variance: Ahmed, *Physics and
Engineering of Radiation Detection*, eq. 6.5.78; sources quoted in
docs/research/receiver-calibration.md)::

    sigma^2(P) = sigma_0^2 + 2 q F B (P + P_b) / R_0

* sigma_0: the detector's and amplifier's own noise (dark current and Johnson noise), W;
* the shot noise of the signal P and of the background P_b, multiplied by the APD's excess
  noise factor F = M^x (Hamamatsu's excess noise figure x), B the noise bandwidth, R_0 the
  unity-gain responsivity (A/W), q the electron's charge;
* the background is sunlight scattered by the scene into the receiver's field of view:
  P_b = E(lambda) d_lambda (rho / pi) A_r Omega eta (a Lambertian scene of reflectance rho
  under solar spectral irradiance E through a filter of width d_lambda, seen in a solid angle
  Omega by an aperture A_r behind optics of transmission eta).

A pulse's echo of peak power S is detected where its peak plus the noise reaches the threshold
T: P_d = Phi((S - T) / sigma(S)) (a threshold on Gaussian noise; the form of MathWorks'
"False Alarm Rate for CFAR Detectors", ``pd = 0.5*erfc((threshold-4)/sqrt(2))``). Noise alone
crosses T upwards at Rice's rate (Rice 1944; for noise of a flat spectrum up to B, Bendat &
Piersol's Example 5.12, halved for up-crossings)::

    FAR = (B / sqrt(3)) exp(-T^2 / (2 sigma_n^2))

with sigma_n = sigma(0), so a threshold is a false-alarm rate: :func:`threshold_for_rate`.
False alarms within a pulse's listening time t are Poisson with mean FAR t, at uniform times;
each alarm's peak exceeds T by an exponential of mean sigma_n^2 / T: over a high level the
noise near a crossing is a parabola whose slope at the crossing is Rayleigh-distributed (Rice),
so the excursion's top, slope^2 / (2 lambda_2 T) above T, is exponential (the asymptotic form
for T of several sigma_n; ``tests/sensor/test_detection.py`` measures it on filtered noise).
Huntington et al. (Opt. Eng. 57, 073106, 2018) show an APD's real tails are heavier than the
Gaussian's, so the threshold a real receiver needs for a rate can be higher: a stated
limitation.
"""

import math
from dataclasses import dataclass

import numpy as np
from scipy.special import ndtr, ndtri

ELECTRON_CHARGE_C = 1.602176634e-19  # SI 2019 exact


@dataclass(frozen=True)
class Detector:
    """A receiver's noise: what turns a received power into a detection probability."""

    responsivity_a_w: float  # R_0, unity gain, at the laser's wavelength
    excess_noise: float  # F
    bandwidth_hz: float  # B, the noise bandwidth of the receiver's electronics
    own_noise_w: float  # sigma_0, dark and amplifier noise referred to the optical input
    filter_nm: float  # d_lambda, the optical band-pass filter's width
    field_sr: float  # Omega, the receiver's field of view
    shot: bool = True  # False: no shot noise, sigma = sigma_0 at every power

    def __post_init__(self) -> None:
        for key in ("responsivity_a_w", "bandwidth_hz", "own_noise_w", "filter_nm", "field_sr"):
            value = getattr(self, key)
            if not (isinstance(value, float | int) and math.isfinite(value) and value > 0):
                raise ValueError(f"{key}={value!r}: expected a positive number")
        if not (math.isfinite(self.excess_noise) and self.excess_noise >= 1.0):
            raise ValueError(f"excess_noise={self.excess_noise!r}: expected F >= 1")


def background_w(
    detector: Detector,
    irradiance_w_m2_nm: float,
    reflectance,
    aperture_area_m2: float,
    optics_efficiency: float,
):
    """P_b (W): sunlight of spectral irradiance E (W m^-2 nm^-1) scattered by a Lambertian
    scene of ``reflectance`` filling the field of view, through the filter and the optics.

    detector : its filter width d_lambda and field of view Omega
    irradiance_w_m2_nm : E at the laser's wavelength (0: night)
    reflectance : rho of the scene, any shape
    aperture_area_m2, optics_efficiency : the receiver's A_r and eta
    """
    radiance = irradiance_w_m2_nm * detector.filter_nm * np.asarray(reflectance) / math.pi
    return radiance * aperture_area_m2 * detector.field_sr * optics_efficiency


def noise_w(detector: Detector, signal_w, background_w=0.0):
    """sigma(P) (W): the noise on a received power ``signal_w`` (any shape) over a background."""
    if not detector.shot:
        return np.full(np.shape(signal_w), float(detector.own_noise_w))
    shot = (
        2.0
        * ELECTRON_CHARGE_C
        * detector.excess_noise
        * detector.bandwidth_hz
        * (np.asarray(signal_w, dtype=np.float64) + background_w)
        / detector.responsivity_a_w
    )
    return np.sqrt(detector.own_noise_w**2 + shot)


def false_alarm_rate_hz(detector: Detector, threshold_w, sigma_n_w):
    """Rice's rate of upward crossings of ``threshold_w`` by noise of sigma ``sigma_n_w`` and
    a flat spectrum up to the detector's bandwidth, per second."""
    t = np.asarray(threshold_w, dtype=np.float64)
    return detector.bandwidth_hz / math.sqrt(3.0) * np.exp(-(t**2) / (2.0 * sigma_n_w**2))


def threshold_for_rate(detector: Detector, rate_hz: float, sigma_n_w: float) -> float:
    """The threshold (W) at which noise of sigma ``sigma_n_w`` crosses upwards ``rate_hz``
    times a second (:func:`false_alarm_rate_hz` inverted); a ValueError for a rate at or above
    B / sqrt(3), the rate of crossing the mean."""
    top = detector.bandwidth_hz / math.sqrt(3.0)
    if not 0.0 < rate_hz < top:
        raise ValueError(f"rate_hz={rate_hz!r}: expected a rate in (0, B / sqrt(3) = {top:g})")
    return sigma_n_w * math.sqrt(2.0 * math.log(top / rate_hz))


def detection_probability(signal_w, threshold_w, sigma_w):
    """P_d = Phi((S - T) / sigma): the chance that a peak of ``signal_w`` plus Gaussian noise
    of ``sigma_w`` reaches ``threshold_w`` (broadcast shape)."""
    s = np.asarray(signal_w, dtype=np.float64)
    return ndtr((s - threshold_w) / np.asarray(sigma_w, dtype=np.float64))


def snr_for_probability(probability: float, threshold_snr: float) -> float:
    """The signal-to-noise ratio S / sigma at which P_d is ``probability`` for a threshold of
    ``threshold_snr`` sigmas (noise taken as the same at S as at the threshold)."""
    return threshold_snr + float(ndtri(probability))


def detect(g: np.random.Generator, signal_w, threshold_w, sigma_w):
    """Each peak's measured power (the signal plus one standard normal draw times sigma, in
    the signal's order) and whether it reaches the threshold: (measured W, detected bool)."""
    s = np.asarray(signal_w, dtype=np.float64)
    measured = s + np.asarray(sigma_w) * g.standard_normal(s.shape)
    return measured, measured >= threshold_w


def false_alarms(
    g: np.random.Generator, pulses: int, rate_hz: float, listen_s: float, threshold_w, sigma_n_w
):
    """The noise's own echoes in ``pulses`` pulses: each pulse's Poisson count of mean
    ``rate_hz`` x ``listen_s``, then per alarm a uniform time in [0, listen_s) and a peak of
    T + an exponential of mean sigma_n^2 / T. Returns (pulse index, time s, peak W), in pulse
    order.

    g : the random stream, read in that order (counts, then two uniforms an alarm)
    rate_hz, sigma_n_w : Rice's rate and the noise's sigma without signal, one for every pulse
        or (pulses,) each its own
    threshold_w : T
    """
    mean = np.broadcast_to(np.asarray(rate_hz, dtype=np.float64) * listen_s, (pulses,))
    counts = g.poisson(mean)
    pulse = np.repeat(np.arange(pulses), counts)
    draws = g.random((len(pulse), 2))
    time_s = draws[:, 0] * listen_s
    sigma = np.broadcast_to(np.asarray(sigma_n_w, dtype=np.float64), (pulses,))[pulse]
    peak_w = threshold_w - sigma**2 / threshold_w * np.log1p(-draws[:, 1])
    return pulse, time_s, peak_w
