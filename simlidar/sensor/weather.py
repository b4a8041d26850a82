"""Fog's own echo: the soft-target backscatter of a pulse's path (issue 41, item 4).

Fog takes power from every pulse (two-way Beer-Lambert extinction, alpha from the visibility by
Koschmieder's law: :func:`simlidar.sensor.receiver.koschmieder_extinction_per_m`) and sends some
back from every metre of the path: the soft target of Hahner et al. (ICCV 2021; their code
``MartinHahner/LiDAR_fog_sim``, ``theory.py``: ``P_R_fog_soft``). For a pulse of power shape
``P_0 g(t)`` the fog between the sensor and the first hard surface at R_h adds to the received
waveform::

    P_fog(t) = P_0 A_r eta beta  int_0^R_h  g(t - 2R'/c) xi(R') exp(-2 alpha R') / R'^2  dR'

(Hahner et al.'s integral over the pulse, ``C_A P_0 beta int sin^2(...) exp(-2 alpha (R - ct/2))
/ (R - ct/2)^2 xi(R - ct/2) dt`` with ``C_A = c eta A_r / 2``, in range instead of time; here
the pulse is the receiver's Gaussian, :mod:`simlidar.sensor.waveform`). ``beta`` is the fog's
backscatter coefficient, ``0.046 / MOR`` per metre and steradian (Hahner et al.'s
``ParameterSet.beta = 0.046 / self.mor``), and ``xi`` the crossover function of a biaxial
sensor: 0 before the receiver's field of view meets the beam (``r_1``), 1 once it covers it
(``r_2``), linear between (Hahner et al.'s default ``linear_xsi``). No Velodyne figure for r_1
and r_2 was found; they are made here from the biaxial geometry Hahner et al.'s parameter set
gives (``D = 0.1`` m between transmitter and receiver, aperture radii 0.01 m, opening angles
2 and 3.5 degrees) by the formulas beside it (their ``R_1``, ``R_2``: "see Figure 2 and
Equation (11) in [1]"), 1.67 m and 7.64 m: an assumption, said so in docs/sensor-model.md.
(Their sliders' defaults, 0.9 and 1.0 m, put the fog's echo at 1.2 m and make it the strongest
echo of 77 % of pulses at 200 m visibility, which no fog-chamber report describes.) A sub-ray
of a beam's footprint sees the fog up to its own hard hit, with its share of the power.

Evaluated on the waveform's bins (:data:`simlidar.sensor.waveform.BIN_NS`), the path cut into
slabs of ``SLAB_M`` (a fifth of the 4 ns pulse's range sigma), as a table of the fog waveform of
a beam blocked at each slab; only as far as the fog could reach ``FLOOR`` of the detection
threshold unblocked (beyond, it is too faint to make or move an echo).

Rain after LISA (Kilic et al. 2021; their code ``velatkilic/LISA``, ``python_old/
atmos_models.py``, the paper's): drops of the Marshall-Palmer size distribution (``N_MP_rain``:
N(D) = 8000 exp(-Lambda D) per m^3 and mm, Lambda = 4.1 R^-0.21 per mm, R in mm/h) take power
from every pulse, alpha = (pi / 4) 1e-6 int D^2 Q_ext N(D) dD per metre (LISA's ``alpha``), with
Q_ext = 2, the large-particle limit (van de Hulst 1957; LISA's own Mie table for water at 905 nm
gives 2.01 to 2.03 above 0.05 mm), so alpha = pi 1e-6 N0 / Lambda^3 (1.56e-3 per m at 10 mm/h;
0.365 R^0.63 per km). Each drop in the beam is a small target (LISA's ``lisa_mc``): its echo is
the range equation's for the Fresnel reflectance of water at normal incidence, ((n - 1) / (n +
1))^2 with n = 1.328 (LISA's default), times the share of the beam it covers, min(D^2 / (theta_h
theta_v r^2), 1) (LISA: ``min((D / D_b(r))^2, 1)``, for a circular beam), and, as the fog's,
the crossover of the biaxial receiver. LISA samples every drop over 0.05 mm in the beam's cone;
here only the drops whose echo could reach ``RAIN_FLOOR`` of the threshold are sampled (a
Poisson process restricted to that region of size and range, exact for those drops; the
others' summed echo within a pulse's reach stays far below the threshold:
``tests/sensor/test_weather.py``), and their echoes join the pulse's waveform, as the fog's
does, instead of LISA's one-point choice between the target and the strongest drop.
"""

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from simlidar.sensor.model import SPEED_OF_LIGHT_M_PER_S
from simlidar.sensor.waveform import fit_peaks, peak_bins

BACKSCATTER_TIMES_MOR = 0.046  # 1/sr: beta = 0.046 / MOR (Hahner et al. 2021, ParameterSet)
# Hahner et al. 2021's biaxial geometry (ParameterSet: D, ROH_T, ROH_R, GAMMA_T_DEG,
# GAMMA_R_DEG), an assumption for the VLP-16
SEPARATION_M, APERTURE_T_M, APERTURE_R_M = 0.1, 0.01, 0.01
OPENING_T_DEG, OPENING_R_DEG = 2.0, 3.5


def _crossover_ranges() -> tuple[float, float]:
    """r_1, r_2 of the biaxial geometry above (Hahner et al.'s R_1, R_2 formulas)."""
    tan_t = math.tan(math.radians(OPENING_T_DEG) / 2.0)
    tan_r = math.tan(math.radians(OPENING_R_DEG) / 2.0)
    r_1 = (SEPARATION_M - APERTURE_T_M - APERTURE_R_M) / (tan_t + tan_r)
    r_2 = (SEPARATION_M - APERTURE_R_M + APERTURE_T_M) / (tan_r - tan_t)
    return r_1, r_2


CROSSOVER_M = _crossover_ranges()  # (1.666, 7.635) m
SLAB_M = 0.05  # integration step along the path
FLOOR = 0.01  # the fog is tabulated while its unblocked waveform can reach this x threshold
C_M_PER_NS = SPEED_OF_LIGHT_M_PER_S * 1e-9


def backscatter_per_m_sr(visibility_m: float) -> float:
    """The fog's backscatter coefficient beta (1 / (m sr)) at meteorological visibility V."""
    return BACKSCATTER_TIMES_MOR / visibility_m


def crossover(range_m, ranges: tuple[float, float] = CROSSOVER_M):
    """xi(R): the share of the beam the receiver sees at range R (linear from r_1 to r_2,
    ``ranges``; Hahner et al.'s geometry by default)."""
    low, high = ranges
    return np.clip((np.asarray(range_m, dtype=float) - low) / (high - low), 0.0, 1.0)


@dataclass(frozen=True)
class FogTable:
    """The fog's waveform for a beam of weight 1 blocked at each slab, on the waveform's bins.

    ``watts[k, j]``: the power at bin ``first_bin + k`` (time ``(first_bin + k) * bin_ns``)
    from the fog in front of slab ``j`` (ranges up to ``CROSSOVER_M[0] + (j + 1) * SLAB_M``); a
    beam blocked nearer than the first slab sees none, one blocked beyond the last (or not
    blocked) sees column -1."""

    first_bin: int
    watts: np.ndarray  # (K, J) float64
    start_m: float  # range of the first slab's near edge (r_1)
    bin_ns: float  # the waveform's bins

    @property
    def last_bin(self) -> int:
        return self.first_bin + len(self.watts) - 1

    @cached_property
    def peaks(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The peaks of every column's waveform alone (the fog where no surface adds to it),
        with their three-point Gaussian fits: (column, bin, time ns, power W), column by
        column, in time order."""
        columns = self.watts.shape[1]
        values = self.watts.T.ravel()  # column by column
        stretch = np.repeat(np.arange(columns), len(self.watts))
        at = peak_bins(values, stretch)
        shift, top = fit_peaks(values, at)
        column, row = np.divmod(at, len(self.watts))
        k = row + self.first_bin
        return column, k, (k + shift) * self.bin_ns, top

    def column(self, blocked_m: np.ndarray) -> np.ndarray:
        """The column of each range a beam is blocked at (NaN: not blocked): -1 for nearer
        than the first slab (no fog), else the last slab in front of it."""
        blocked = np.asarray(blocked_m, dtype=float)
        slabs = self.watts.shape[1]
        reach = np.where(np.isnan(blocked), self.start_m + (slabs + 1) * SLAB_M, blocked)
        j = np.floor((reach - self.start_m) / SLAB_M).astype(np.int64) - 1
        return np.clip(j, -1, slabs - 1)


def fog_table(
    peak_power_w: float,
    aperture_area_m2: float,
    optics_efficiency: float,
    threshold_w: float,
    visibility_m: float,
    extinction_per_m: float,
    sigma_ns: float,
    bin_ns: float,
    max_range_m: float,
    backscatter: float | None = None,
    crossover_m: tuple[float, float] = CROSSOVER_M,
) -> FogTable | None:
    """The fog's waveform table (:class:`FogTable`) for a receiver and a fog; None where even
    unblocked it never reaches ``FLOOR`` x the threshold.

    peak_power_w, aperture_area_m2, optics_efficiency : the receiver's P_0 (W), A_r (m^2) and
        eta (:class:`simlidar.sensor.receiver.Receiver`)
    threshold_w : the receiver's detection threshold (W)
    visibility_m : the fog's meteorological visibility (m), which sets its backscatter beta
    extinction_per_m : the atmosphere's alpha (1/m) on the way out and back: the fog's
        Koschmieder alpha, plus a rain's where it rains too
    sigma_ns : the Gaussian pulse's sigma (ns; :func:`simlidar.sensor.waveform.pulse_sigma_ns`)
    bin_ns : the waveform's bin (ns; :data:`simlidar.sensor.waveform.BIN_NS`)
    max_range_m : the sensor's range (m): the slabs reach no further
    backscatter : beta (1 / (m sr)); None: Hahner et al.'s 0.046 / V
    crossover_m : the receiver's r_1, r_2 (Hahner et al.'s geometry by default)
    """
    beta = backscatter_per_m_sr(visibility_m) if backscatter is None else backscatter
    constant = peak_power_w * aperture_area_m2 * optics_efficiency * beta
    start = max(crossover_m[0], SLAB_M)
    centres = start + (np.arange(int((max_range_m - start) / SLAB_M)) + 0.5) * SLAB_M
    density = crossover(centres, crossover_m) * np.exp(-2.0 * extinction_per_m * centres)
    density = density / centres**2
    slab_w = constant * density * SLAB_M  # each slab's echo, a Gaussian pulse of this peak
    # the unblocked fog's waveform is at most the slabs within a pulse's reach summed
    reach = int(math.ceil(4.0 * sigma_ns * C_M_PER_NS / 2.0 / SLAB_M))
    window = np.convolve(slab_w, np.ones(2 * reach + 1), mode="same")
    faint = window < FLOOR * threshold_w
    if faint.all():
        return None
    last = int(np.nonzero(~faint)[0].max()) + 1
    slab_w, centres = slab_w[:last], centres[:last]
    times = 2.0 * centres / C_M_PER_NS
    first_bin = int(math.floor((times[0] - 4.0 * sigma_ns) / bin_ns))
    last_bin = int(math.ceil((times[-1] + 4.0 * sigma_ns) / bin_ns))
    t = np.arange(first_bin, last_bin + 1) * bin_ns
    pulses = np.exp(-((t[:, None] - times[None, :]) ** 2) / (2.0 * sigma_ns**2))
    return FogTable(first_bin, np.cumsum(pulses * slab_w[None, :], axis=1), start, bin_ns)


# Rain: LISA (Kilic et al. 2021), python_old/atmos_models.py
RAIN_N0_PER_M3_MM = 8000.0  # Marshall & Palmer 1948, as LISA's N_MP_rain
RAIN_SLOPE = (4.1, -0.21)  # Lambda = 4.1 R^-0.21 per mm (Marshall & Palmer 1948, as LISA)
EXTINCTION_EFFICIENCY = 2.0  # Q_ext of drops far larger than the wavelength (van de Hulst 1957)
WATER_INDEX = 1.328  # water's refractive index at 905 nm: LISA's default m
RAIN_FLOOR = 0.1  # drops are sampled where their echo could reach this x the threshold
MAX_RAIN_MM_H = 500.0  # the largest rate accepted (heavier than any hour on record)
_GAMMA_SHAPE = 2.5  # sampled diameters have density ~ N(D) D^1.5 (see Rain)


def rain_slope_per_mm(rate_mm_h: float) -> float:
    """Lambda of the Marshall-Palmer distribution (per mm) at rain rate R (mm/h)."""
    return RAIN_SLOPE[0] * rate_mm_h ** RAIN_SLOPE[1]


def rain_extinction_per_m(rate_mm_h: float) -> float:
    """The rain's extinction coefficient alpha (1/m) at rate R (mm/h; 0: no rain)::

    alpha = (pi / 4) 1e-6 Q_ext int D^2 N0 exp(-Lambda D) dD = (pi / 2) 1e-6 Q_ext N0 / Lambda^3
    """
    if rate_mm_h <= 0.0:
        return 0.0
    slope = rain_slope_per_mm(rate_mm_h)
    return 0.5 * math.pi * 1e-6 * EXTINCTION_EFFICIENCY * RAIN_N0_PER_M3_MM / slope**3


def fresnel_reflectance(index: float) -> float:
    """The reflectance of a smooth surface at normal incidence, ((n - 1) / (n + 1))^2."""
    return ((index - 1.0) / (index + 1.0)) ** 2


@dataclass(frozen=True)
class Rain:
    """The drops of a rain a receiver could see: in each pulse's beam, the Poisson process of
    the drops (diameter D, range r) whose echo, bounded above by ``drop_w * D^2 / r^4`` (the
    echo without the cap at a full beam, the crossover and extinction, each at most 1), reaches
    ``RAIN_FLOOR`` x the threshold: r <= reach sqrt(D) (D in mm). Their number in a beam is
    Poisson, of mean ``mean_per_pulse`` = (pi / 12) theta_h theta_v N0 reach^3 int N(D) / N0
    D^1.5 dD over D >= ``smallest_mm`` (where reach sqrt(D) is the crossover's r_1: smaller
    drops are never seen); a drop's diameter has density ~ exp(-Lambda D) D^1.5 there (a gamma
    of shape 2.5, truncated) and its range is uniform in the cone's volume up to reach sqrt(D).
    """

    rate_mm_h: float
    slope_per_mm: float  # Lambda
    full_w: float  # K rho_w: the echo of a drop that fills the beam is full_w / r^2
    solid_angle: float  # theta_h theta_v (rad^2): a drop covers D^2 / (theta_h theta_v r^2)
    reach_m: float  # r <= reach_m sqrt(D / mm)
    smallest_mm: float
    mean_per_pulse: float
    nearest_m: float  # the crossover's r_1: no drop nearer is seen
    crossover_m: tuple[float, float] = CROSSOVER_M

    def draw(self, g: np.random.Generator, pulses: int):
        """One sample's drops in its ``pulses`` beams: (pulse index, range m, diameter mm),
        from ``pulses`` Poisson counts then two uniforms a drop (diameter, range)."""
        from scipy.special import gammaincc, gammainccinv

        counts = g.poisson(self.mean_per_pulse, pulses)
        u = g.random((int(counts.sum()), 2))
        pulse = np.repeat(np.arange(pulses), counts)
        top = gammaincc(_GAMMA_SHAPE, self.slope_per_mm * self.smallest_mm)
        diameter_mm = gammainccinv(_GAMMA_SHAPE, (1.0 - u[:, 0]) * top) / self.slope_per_mm
        range_m = self.reach_m * np.sqrt(diameter_mm) * np.cbrt(u[:, 1])
        return pulse, range_m, diameter_mm

    def echo_w(self, range_m, diameter_mm, extinction_per_m: float):
        """A drop's echo (W, the range equation's peak power): LISA's, with the crossover."""
        r = np.asarray(range_m, dtype=float)
        d_m = np.asarray(diameter_mm, dtype=float) * 1e-3
        share = np.minimum(d_m**2 / (self.solid_angle * r**2), 1.0)
        seen = crossover(r, self.crossover_m)
        return self.full_w * share * seen * np.exp(-2.0 * extinction_per_m * r) / r**2


def rain(
    peak_power_w: float,
    aperture_area_m2: float,
    optics_efficiency: float,
    threshold_w: float,
    divergence_h_mrad: float,
    divergence_v_mrad: float,
    rate_mm_h: float,
    crossover_m: tuple[float, float] = CROSSOVER_M,
) -> Rain | None:
    """The rain (:class:`Rain`) a receiver sees at rate R (mm/h); None for no rain.

    peak_power_w, aperture_area_m2, optics_efficiency : the receiver's P_0 (W), A_r (m^2) and
        eta (:class:`simlidar.sensor.receiver.Receiver`)
    threshold_w : the receiver's detection threshold (W): only drops whose echo could reach
        ``RAIN_FLOOR`` of it are sampled
    divergence_h_mrad, divergence_v_mrad : the beam's full-angle divergence along and across
        the scan (mrad), theta_h and theta_v: a drop of diameter D at range r covers
        min(D^2 / (theta_h theta_v r^2), 1) of the beam
    rate_mm_h : the rain's rate R (mm/h; 0 or below: no rain)
    crossover_m : the receiver's r_1, r_2 (Hahner et al.'s geometry by default)
    """
    from scipy.special import gamma, gammaincc

    if rate_mm_h <= 0.0:
        return None
    slope = rain_slope_per_mm(rate_mm_h)
    full_w = (
        peak_power_w * aperture_area_m2 * optics_efficiency * fresnel_reflectance(WATER_INDEX)
    ) / math.pi
    solid = divergence_h_mrad * 1e-3 * divergence_v_mrad * 1e-3
    # drop_w D_m^2 / r^4 >= FLOOR threshold  <=>  r <= (drop_w 1e-6 D_mm^2 / (FLOOR th))^(1/4)
    reach = (full_w / solid * 1e-6 / (RAIN_FLOOR * threshold_w)) ** 0.25
    nearest = max(crossover_m[0], 0.05)
    smallest = (nearest / reach) ** 2
    moment = gamma(_GAMMA_SHAPE) * gammaincc(_GAMMA_SHAPE, slope * smallest) / slope**_GAMMA_SHAPE
    mean = math.pi / 12.0 * solid * RAIN_N0_PER_M3_MM * reach**3 * moment
    return Rain(rate_mm_h, slope, full_w, solid, reach, smallest, float(mean), nearest, crossover_m)
