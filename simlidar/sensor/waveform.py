"""A pulse's received waveform, its echoes and the returns a sensor reports (issue 41).

The waveform is HELIOS++'s full-waveform model (Winiwarter et al. 2022; its
``FullWaveformPulseRunnable``): every sub-ray echo (:mod:`simlidar.sensor.footprint`) adds the
emitted pulse's shape, scaled by its received power, at its time of flight, and the sum is
sampled in bins. The pulse is a Gaussian whose full width at half maximum is the receiver's
``pulse_width_ns`` (the issue's "full waveform from a Gaussian pulse"; HELIOS++ itself uses
an asymmetric pulse), so its peak value is the power of the sub-rays under it::

    P(t) = sum_s p_s exp(-(t - t_s)^2 / (2 sigma^2)),   sigma = FWHM / (2 sqrt(2 ln 2))

sampled every ``BIN_NS`` (HELIOS++'s default ``binSize_ns`` = 0.25, ``FWFSettings.h``; the
VLP-16's digitiser rate is not published). Echoes are the waveform's local maxima (HELIOS++
detects peaks the same way); each is placed by a Gaussian fit through its bin and the two
beside it (a parabola through the log of the three values: exact for an echo of one surface),
and it is detected when its fitted peak power reaches the receiver's threshold. Echoes closer
than about the pulse's width merge into one peak between them: the mixed pixels of real
sensors. The returns a sensor reports are chosen among the detected echoes by its return mode
(VLP-16 manual sec. 9.3.2 p. 57): ``strongest``, ``last``, or ``dual``: the last and the
strongest, and "if the strongest return is also the last return, then the second-strongest
return is provided".
"""

import math
from dataclasses import dataclass

import numpy as np

BIN_NS = 0.25  # HELIOS++ FWFSettings.h binSize_ns (default)
REACH_SIGMAS = 4.0  # each pulse's waveform is sampled this many sigmas beyond its echoes
# beyond this many sigmas an echo's Gaussian is exp(x) with x < -750: exactly 0.0 in float64
# (the smallest subnormal is exp(-744.4)), so adding it changes no bit and it is not computed
ZERO_SIGMAS = math.sqrt(1500.0)
CHUNK_VALUES = 1 << 22  # waveform samples x sub-rays evaluated at once (memory: ~32 MB)


def pulse_sigma_ns(pulse_width_ns: float) -> float:
    """The Gaussian pulse's sigma from its full width at half maximum."""
    return pulse_width_ns / (2.0 * math.sqrt(2.0 * math.log(2.0)))


def waveform(times_ns, powers_w, sigma_ns: float, t_ns) -> np.ndarray:
    """P(t) of one pulse's sub-ray echoes (``times_ns``, ``powers_w``: (S,), NaN time: no hit)
    at the times ``t_ns`` (any shape): the formula above, for pictures and checks."""
    times = np.asarray(times_ns, dtype=np.float64)
    hit = ~np.isnan(times)
    t = np.asarray(t_ns, dtype=np.float64)[..., None]
    shape = np.exp(-((t - times[hit]) ** 2) / (2.0 * sigma_ns**2))
    return (shape * np.asarray(powers_w, dtype=np.float64)[hit]).sum(axis=-1)


@dataclass(frozen=True)
class Echoes:
    """The waveform peaks of P pulses, in order of time, NaN-padded to the most any pulse has."""

    time_ns: np.ndarray  # (P, E) float64, the fitted peak time
    power_w: np.ndarray  # (P, E) float64, the fitted peak power; NaN: no echo
    count: np.ndarray  # (P,) int64, peaks a pulse has (detected or not)


def fit_peaks(values: np.ndarray, at: np.ndarray):
    """Three-point Gaussian fits at the peak bins ``at`` of ``values``: (offset in bins, peak
    power)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        low, mid, high = (np.log(values[at + i]) for i in (-1, 0, 1))
        curve = low - 2.0 * mid + high  # < 0 at a strict peak
        shift = np.where(curve < 0.0, 0.5 * (low - high) / curve, 0.0)
        top = np.where(curve < 0.0, mid - 0.25 * (low - high) * shift, mid)
    return shift, np.exp(top)


def peak_bins(values: np.ndarray, stretch: np.ndarray) -> np.ndarray:
    """The bins of ``values`` above the bin before and not below the one after, both of the
    same ``stretch``."""
    peak = np.zeros(len(values), bool)
    peak[1:-1] = (
        (stretch[:-2] == stretch[1:-1])
        & (stretch[2:] == stretch[1:-1])
        & (values[1:-1] > values[:-2])
        & (values[1:-1] >= values[2:])
    )
    return np.flatnonzero(peak & (values > 0.0))


def _windows(times: np.ndarray, reach_ns: float, bin_ns: float):
    """The bins a pulse's waveform is evaluated on, without fog: a window from reach_ns before
    to reach_ns after each run of its echoes, a run ending where the next echo is more than two
    windows' reach away. Returns each window's pulse, first and last bin, in order of pulse
    and time. The waveform is the same sum of every echo of the pulse on every bin; what is
    skipped, a gap more than 4 sigma from every echo, holds no peak (every Gaussian is convex
    there, and so is their sum), so the echoes are those of one window from the first echo to
    the last, bit for bit. A pulse with one run (one surface) has the window it always had."""
    if times.shape[1] == 1:  # one echo a pulse: one window each
        p = np.flatnonzero(~np.isnan(times[:, 0]))
        t = times[p, 0]
        return p, np.floor((t - reach_ns) / bin_ns), np.ceil((t + reach_ns) / bin_ns)
    ordered = np.sort(times, axis=1)  # each pulse's echoes in time order, NaN last
    p, c = np.nonzero(~np.isnan(ordered))
    t = ordered[p, c]
    new = np.ones(len(p), bool)
    new[1:] = (p[1:] != p[:-1]) | (t[1:] - t[:-1] > 2.0 * reach_ns + 2.0 * bin_ns)
    starts = np.flatnonzero(new)
    ends = np.r_[starts[1:], len(t)] - 1
    first = np.floor((t[starts] - reach_ns) / bin_ns)
    last = np.ceil((t[ends] + reach_ns) / bin_ns)
    return p[starts], first, last


def echoes(
    times_ns: np.ndarray,
    powers_w: np.ndarray,
    sigma_ns: float,
    bin_ns=BIN_NS,
    fog=None,
    fog_columns: np.ndarray | None = None,
    extra_times_ns: np.ndarray | None = None,
    extra_powers_w: np.ndarray | None = None,
) -> Echoes:
    """Every local maximum of each pulse's sampled waveform, with its Gaussian fit.

    times_ns, powers_w : (P, S) sub-ray times of flight (NaN: no hit) and received powers
    sigma_ns : the Gaussian pulse's sigma (:func:`pulse_sigma_ns` of its width)
    fog : a :class:`simlidar.sensor.weather.FogTable` (on bins of ``bin_ns``) whose column
        ``fog_columns[p]`` (-1: no fog) adds to pulse p's waveform. Where the pulse's
        surfaces add nothing (beyond 4 sigma of every hit) the waveform is that column alone,
        whose peaks are found once for every pulse that shares it.
    extra_times_ns, extra_powers_w : (P, D) more echoes (the rain's drops; NaN: none), added
        to the sub-rays' sum one column after the other, so that the padding of a block's
        widest pulse adds exactly nothing (a pulse's waveform does not depend on its block)
    """
    times = np.asarray(times_ns, dtype=np.float64)
    powers = np.where(np.isnan(times), 0.0, np.asarray(powers_w, dtype=np.float64))
    extra = np.empty((len(times), 0)) if extra_times_ns is None else extra_times_ns
    extra = np.asarray(extra, dtype=np.float64)
    extra_w = np.zeros(extra.shape) if extra_powers_w is None else extra_powers_w
    extra_w = np.where(np.isnan(extra), 0.0, np.asarray(extra_w, dtype=np.float64))
    pulses = len(times)
    every = np.hstack([times, extra])
    hit = ~np.isnan(every).all(axis=1)
    reach = REACH_SIGMAS * sigma_ns
    if fog is None:  # a window around each run of echoes (see _windows)
        owner, first, last = _windows(every, reach, bin_ns)
    else:  # one window a pulse, from its first echo to its last (the fog fills the gaps)
        seen = np.where(hit[:, None], every, 0.0)  # a pulse without hits: zeros, no warning
        owner = np.arange(pulses)
        first = np.where(hit, np.floor((np.nanmin(seen, axis=1) - reach) / bin_ns), 0)
        last = np.where(hit, np.ceil((np.nanmax(seen, axis=1) + reach) / bin_ns), -1)
    bins = (last - first + 1).astype(np.int64)  # 0 for a pulse without hits
    window = np.repeat(np.arange(len(owner)), bins)
    pulse = owner[window]
    start = np.cumsum(bins) - bins
    k = (first[window] + np.arange(len(window)) - start[window]).astype(np.int64)
    t = k * bin_ns
    values = np.empty(len(pulse))
    rows = max(1, CHUNK_VALUES // max(1, times.shape[1]))
    zero = ZERO_SIGMAS * sigma_ns
    for lo in range(0, len(pulse), rows):
        p, tt = pulse[lo : lo + rows], t[lo : lo + rows]
        # each term computed only where it can be other than 0.0: a sub-ray without a hit
        # (NaN, power 0) and a Gaussian beyond ZERO_SIGMAS are exactly 0.0, so the terms, and
        # their sum in the same order, are those of computing every one, bit for bit
        gap = tt[:, None] - times[p]
        near = np.abs(gap) <= zero
        terms = np.zeros(gap.shape)
        terms[near] = powers[p][near] * np.exp(-(gap[near] ** 2) / (2.0 * sigma_ns**2))
        values[lo : lo + rows] = terms.sum(axis=1)
        part = values[lo : lo + rows]
        for d in range(extra.shape[1]):
            # one column after the other, the bins its echo reaches only (as above: the values
            # are sums of products of non-negative powers, never -0.0, and x + 0.0 is x)
            gap = tt - extra[p, d]
            near = np.flatnonzero(np.abs(gap) <= zero)
            part[near] += extra_w[p[near], d] * np.exp(-(gap[near] ** 2) / (2.0 * sigma_ns**2))
    if fog is not None:  # the fog under the surfaces' echoes
        row, column = k - fog.first_bin, fog_columns[pulse]
        inside = (row >= 0) & (row < len(fog.watts)) & (column >= 0)
        values[inside] += fog.watts[row[inside], column[inside]]
    at = peak_bins(values, window)
    shift, top = fit_peaks(values, at)
    owner, peak_t, peak_w = pulse[at], t[at] + shift * bin_ns, top
    if fog is not None:  # and the fog alone, away from them: its column's own peaks
        col, k_fog, t_fog, w_fog = fog.peaks
        per_column = np.bincount(col, minlength=fog.watts.shape[1])
        mine = fog_columns
        counts = np.where(mine >= 0, per_column[np.maximum(mine, 0)], 0)
        who = np.repeat(np.arange(pulses), counts)
        offset = (np.cumsum(per_column) - per_column)[mine[who]]
        index = offset + np.arange(len(who)) - (np.cumsum(counts) - counts)[who]
        away = (k_fog[index] < first[who]) | (k_fog[index] > last[who])
        owner = np.r_[owner, who[away]]
        peak_t = np.r_[peak_t, t_fog[index][away]]
        peak_w = np.r_[peak_w, w_fog[index][away]]
        order = np.lexsort((peak_t, owner))
        owner, peak_t, peak_w = owner[order], peak_t[order], peak_w[order]
    (time, power), count = by_row(owner, pulses, (peak_t, np.nan), (peak_w, np.nan))
    return Echoes(time, power, count)


def by_row(owner: np.ndarray, rows: int, *columns):
    """Values of rows ``owner`` (sorted, in each row's order) laid out as (rows, most) arrays,
    padded: ``columns`` are (values, fill) pairs. Returns the arrays and each row's count."""
    count = np.bincount(owner, minlength=rows)
    most = int(count.max()) if rows else 0
    rank = np.arange(len(owner)) - (np.cumsum(count) - count)[owner]
    laid = []
    for values, fill in columns:
        out = np.full((rows, most), fill, dtype=np.float64)
        out[owner, rank] = values
        laid.append(out)
    return laid, count


def reported(echo: Echoes, threshold_w: float, mode: str, dual_rule: str = "second_strongest"):
    """The returns a sensor reports of each pulse's echoes: the index (P, R) of each reported
    echo in ``echo`` (-1: none), R = 2 for ``dual`` (the manual's block order: the last return,
    then the strongest, or the second strongest where the strongest is the last; a pulse with
    one detected echo reports it in both, as the manual says the blocks are then identical),
    else 1. ``dual_rule``: the receiver's ``dual_when_strongest_is_last`` (``first``: the
    first echo then)."""
    power = np.where(echo.power_w >= threshold_w, echo.power_w, -np.inf)  # NaN compares False
    found = np.isfinite(power)
    pulses, most = power.shape
    none = np.full(pulses, -1)
    if most == 0:
        return np.full((pulses, 2 if mode == "dual" else 1), -1)
    any_found = found.any(axis=1)
    strongest = np.where(any_found, np.argmax(power, axis=1), none)
    last = np.where(any_found, most - 1 - np.argmax(found[:, ::-1], axis=1), none)
    if mode == "strongest":
        return strongest[:, None]
    if mode == "last":
        return last[:, None]
    if mode != "dual":
        raise ValueError(f"mode={mode!r}: expected strongest, last or dual")
    if dual_rule == "second_strongest":
        others = np.where(np.arange(most)[None, :] == last[:, None], -np.inf, power)
        other = np.where(np.isfinite(others).any(axis=1), np.argmax(others, axis=1), last)
    else:
        other = np.where(any_found, np.argmax(found, axis=1), none)
    second = np.where(strongest == last, other, strongest)
    return np.stack([last, second], axis=1)


def sampled(
    times_ns: np.ndarray,
    powers_w: np.ndarray,
    sigma_ns: float,
    bin_ns: float,
    bins: int,
    fog=None,
    fog_columns: np.ndarray | None = None,
) -> np.ndarray:
    """Each pulse's waveform P(t) sampled at t = k ``bin_ns``, k = 0 .. ``bins`` - 1 (what a
    dataset stores on request): (P, bins) float32, watts.

    times_ns, powers_w : (P, S) as :func:`echoes` takes them (NaN time: no hit); each echo is
        evaluated within ``REACH_SIGMAS`` sigmas of its time (beyond, under 3.4e-4 of its peak)
    sigma_ns : the Gaussian pulse's sigma (:func:`pulse_sigma_ns` of its width)
    fog : a :class:`simlidar.sensor.weather.FogTable` whose bins (of :data:`BIN_NS`) fall on
        every sample (``bin_ns`` a multiple of them), column ``fog_columns[p]`` for pulse p
    """
    times = np.asarray(times_ns, dtype=np.float64)
    powers = np.where(np.isnan(times), 0.0, np.asarray(powers_w, dtype=np.float64))
    pulses = len(times)
    out = np.zeros((pulses, bins), np.float32)
    # every sample within 4 sigma of an echo: from the nearest sample, half a bin more
    reach = int(math.ceil(REACH_SIGMAS * sigma_ns / bin_ns + 0.5))
    offsets = np.arange(-reach, reach + 1)
    pulse, column = np.nonzero(~np.isnan(times))  # in pulse order
    if fog is not None:
        step = int(round(bin_ns / fog.bin_ns))
        row = np.arange(bins) * step - fog.first_bin
        covered = np.flatnonzero((row >= 0) & (row < len(fog.watts)))
    block = max(1, CHUNK_VALUES // bins)  # pulses summed at once, in float64
    for lo in range(0, pulses, block):
        hi = min(lo + block, pulses)
        a, b = np.searchsorted(pulse, [lo, hi])
        p, s = pulse[a:b], column[a:b]
        t = times[p, s]
        k = np.round(t / bin_ns).astype(np.int64)[:, None] + offsets
        inside = (k >= 0) & (k < bins)
        shape = np.exp(-((k * bin_ns - t[:, None]) ** 2) / (2.0 * sigma_ns**2))
        value = powers[p, s][:, None] * shape
        flat = (p[:, None] - lo) * bins + k
        values = np.bincount(flat[inside], value[inside], minlength=(hi - lo) * bins)
        values = values.reshape(hi - lo, bins)
        if fog is not None:
            mine = fog_columns[lo:hi]
            foggy = np.flatnonzero(mine >= 0)
            values[np.ix_(foggy, covered)] += fog.watts[row[covered]][:, mine[foggy]].T
        out[lo:hi] = values
    return out
