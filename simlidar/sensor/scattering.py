"""Fog and rain as populations of water drops: extinction and backscatter from Mie theory over
a drop-size distribution (issue 62, item 5).

A population of spheres of number density N(D) per unit diameter takes power from a beam at
the extinction coefficient and sends it back at the backscatter coefficient::

    alpha = int N(D) (pi D^2 / 4) Q_ext(x) dD                       (1/m)
    beta  = int N(D) (pi D^2 / 4) Q_back(x) / (4 pi) dD             (1/(m sr))

with x = pi D / lambda (Bohren & Huffman 1983, sec. 4.4 and eq. 4.82; the efficiencies of
:mod:`simlidar.sensor.mie`). Their ratio S = alpha / beta is the lidar ratio.

The drops' optics are data (``sensors/atmosphere/water.toml``: water's refractive index, the
fog distributions, the Marshall-Palmer rain, each with its source) and the efficiencies a table
(``sensors/atmosphere/water-mie-<band>.json``) made from them by ``python
benchmark/mie_tables.py``: the size parameter cut into cells of equal width in log x, each cell
holding the mean of Q_ext and Q_back over sizes spread evenly (stratified, jittered by a fixed
seed) across it. Large drops' backscatter rings with x (glory and surface-wave resonances far
narrower than a cell), so a cell's mean, not a value at its centre, is what a population of
drops of every size in the cell sends back. Reading the committed table keeps every dataset's
bytes apart from the numpy version that would compute the series.

Fog is given by its meteorological visibility V, which is defined in visible light: the
distribution's number density is set so that its extinction at 550 nm is Koschmieder's ln(20)
/ V (:func:`simlidar.sensor.receiver.koschmieder_extinction_per_m`), and its extinction and
backscatter at the LiDAR's wavelength follow from the same drops.
"""

import json
import math
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from simlidar.content import content_dir, key_error, read_toml
from simlidar.errors import ConfigError

VISIBLE_NM = 550.0  # the wavelength meteorological visibility is defined at (Koschmieder)
MAX_ATMOSPHERE_BYTES = 64 * 1024
MAX_TABLE_BYTES = 4 * 1024 * 1024


@dataclass(frozen=True)
class MieTable:
    """Cell means of Q_ext and Q_back of water spheres over log-spaced size-parameter cells."""

    band: str  # the table's name: "visible" (550 nm) or "nir" (the LiDARs' 903-905 nm)
    index: complex  # water's refractive index the table was computed for
    edges: np.ndarray  # (C + 1,) the cells' size-parameter edges, log-spaced
    q_ext: np.ndarray  # (C,) each cell's mean
    q_back: np.ndarray  # (C,)
    q_back_error: np.ndarray  # (C,) the standard error of each Q_back mean (sampling)

    def cell(self, x) -> np.ndarray:
        """The cell of each size parameter (0 .. C - 1); a ValueError outside the table."""
        x = np.asarray(x, dtype=np.float64)
        if np.any(x < self.edges[0]) or np.any(x > self.edges[-1]):
            raise ValueError(
                f"size parameter outside the {self.band} table "
                f"[{self.edges[0]:g}, {self.edges[-1]:g}]"
            )
        return np.clip(np.searchsorted(self.edges, x, side="right") - 1, 0, len(self.q_ext) - 1)


def cell_means(m: complex, edges: np.ndarray, samples: int, seed: int = 0, only=None):
    """Q_ext and Q_back of spheres of index ``m`` averaged over each cell of ``edges`` (log x):
    ``samples`` sizes a cell, one in each of ``samples`` equal slices of its log width, at a
    uniform place in it (``numpy.random.default_rng(seed)``). Returns three (C,) arrays: the
    means of Q_ext and Q_back and the standard error of each Q_back mean (its samples' sample
    standard deviation over sqrt(samples)). ``only``: the cells to compute (the others NaN; the
    draws are the same whichever are computed)."""
    from simlidar.sensor.mie import efficiencies

    g = np.random.default_rng(seed)
    cells = len(edges) - 1
    u = (np.arange(samples)[None, :] + g.random((cells, samples))) / samples
    low, high = np.log(edges[:-1])[:, None], np.log(edges[1:])[:, None]
    x = np.exp(low + u * (high - low))  # (C, samples)
    q_ext, q_back, error = np.full(cells, np.nan), np.full(cells, np.nan), np.full(cells, np.nan)
    # a cell at a time: the series' length follows its largest x
    for c in range(cells) if only is None else only:
        e, _, b = efficiencies(x[c], m)
        q_ext[c], q_back[c] = e.mean(), b.mean()
        error[c] = b.std(ddof=1) / np.sqrt(samples)
    return q_ext, q_back, error


def table_to_dict(table: MieTable, made_by: str) -> dict:
    """A table as its JSON file holds it."""
    return {
        "band": table.band,
        "index": [table.index.real, table.index.imag],
        "made_by": made_by,
        "edges": table.edges.tolist(),
        "q_ext": table.q_ext.tolist(),
        "q_back": table.q_back.tolist(),
        "q_back_error": table.q_back_error.tolist(),
    }


def checked_table(where: str, data) -> MieTable:
    """A table of a JSON file's content, every field checked: a ConfigError naming it."""
    if not isinstance(data, dict):
        raise ConfigError(f"{where}: expected a table of band, index, edges, q_ext, q_back")
    arrays = {}
    for key in ("edges", "q_ext", "q_back", "q_back_error"):
        value = data.get(key)
        ok = isinstance(value, list) and all(
            isinstance(v, float | int) and not isinstance(v, bool) for v in value
        )
        array = np.asarray(value if ok else [], dtype=np.float64)
        if not ok or len(array) < 2 or not np.all(np.isfinite(array)) or np.any(array < 0):
            raise key_error(where, key, "a list of non-negative numbers", value)
        arrays[key] = array
    edges = arrays["edges"]
    if not (edges[0] > 0 and np.all(np.diff(edges) > 0)):
        raise key_error(where, "edges", "increasing positive size parameters", data["edges"])
    for key in ("q_ext", "q_back", "q_back_error"):
        if len(arrays[key]) != len(edges) - 1:
            raise key_error(where, key, f"{len(edges) - 1} values, one a cell", data[key])
    index = data.get("index")
    pair = isinstance(index, list) and len(index) == 2
    if not (pair and all(isinstance(v, float) for v in index)):
        raise key_error(where, "index", "[n, k]", index)
    band = data.get("band")
    if band not in ("visible", "nir"):
        raise key_error(where, "band", "'visible' or 'nir'", band)
    return MieTable(
        band, complex(*index), edges, arrays["q_ext"], arrays["q_back"], arrays["q_back_error"]
    )


def table_path(band: str) -> Path:
    return content_dir("sensors") / "atmosphere" / f"water-mie-{band}.json"


@lru_cache(maxsize=4)
def load_table(band: str) -> MieTable:
    """The committed Mie table of water for ``band`` ("visible" or "nir")."""
    path = table_path(band)
    where = f"Mie table {path}"
    text = path.read_bytes()
    if len(text) > MAX_TABLE_BYTES:
        raise ConfigError(f"{where}: {len(text)} bytes, expected at most {MAX_TABLE_BYTES}")
    return checked_table(where, json.loads(text))


@dataclass(frozen=True)
class FogDistribution:
    """A modified gamma distribution of fog drop radii, n(r) = a r^alpha exp(-b r^gamma)
    (number per cm^3 and micrometre, r in micrometres)."""

    name: str
    a: float
    alpha: float
    b: float
    gamma: float

    def density(self, radius_um) -> np.ndarray:
        r = np.asarray(radius_um, dtype=np.float64)
        return self.a * r**self.alpha * np.exp(-self.b * r**self.gamma)

    @property
    def number_per_cm3(self) -> float:
        """N = int n(r) dr = a Gamma((alpha + 1) / gamma) / (gamma b^((alpha + 1) / gamma))."""
        k = (self.alpha + 1.0) / self.gamma
        return self.a * math.gamma(k) / (self.gamma * self.b**k)

    @property
    def mode_radius_um(self) -> float:
        """The radius where n(r) peaks, (alpha / (b gamma))^(1 / gamma)."""
        return (self.alpha / (self.b * self.gamma)) ** (1.0 / self.gamma)


@dataclass(frozen=True)
class Atmosphere:
    """``sensors/atmosphere/water.toml``: water's index per band, the fogs, the rain."""

    index: dict  # band -> complex
    fogs: dict  # name -> FogDistribution
    rain_n0_per_m3_mm: float
    rain_slope: tuple[float, float]  # Lambda = slope[0] R^slope[1] per mm


def load_atmosphere(path: str | Path | None = None) -> Atmosphere:
    """The drops' optics (``sensors/atmosphere/water.toml`` or the file ``path``), every key
    checked: a ConfigError naming the file and the key otherwise."""
    path = Path(path) if path is not None else content_dir("sensors") / "atmosphere/water.toml"
    where = f"atmosphere {path}"
    data = read_toml(path, MAX_ATMOSPHERE_BYTES, ConfigError, where)
    index = {}
    for band in ("visible", "nir"):
        pair = data.get("index", {}).get(band)
        if not (
            isinstance(pair, list) and len(pair) == 2 and all(isinstance(v, float) for v in pair)
        ) or not (pair[0] > 0 and pair[1] >= 0):
            raise key_error(where, f"index.{band}", "[n, k] with n > 0, k >= 0", pair)
        index[band] = complex(*pair)
    fogs = {}
    for name, table in data.get("fog", {}).items():
        values = {}
        for key in ("a", "alpha", "b", "gamma"):
            value = table.get(key) if isinstance(table, dict) else None
            if not isinstance(value, float | int) or isinstance(value, bool) or not value > 0:
                raise key_error(where, f"fog.{name}.{key}", "a positive number", value)
            values[key] = float(value)
        fogs[name] = FogDistribution(name, **values)
    if not fogs:
        raise key_error(where, "fog", "tables [fog.<name>]", data.get("fog"))
    rain = data.get("rain", {})
    n0, slope = rain.get("n0_per_m3_mm"), rain.get("slope")
    if not isinstance(n0, float | int) or not n0 > 0:
        raise key_error(where, "rain.n0_per_m3_mm", "a positive number", n0)
    if not (isinstance(slope, list) and len(slope) == 2 and slope[0] > 0 and slope[1] < 0):
        raise key_error(where, "rain.slope", "[c, e] with c > 0, e < 0", slope)
    return Atmosphere(index, fogs, float(n0), (float(slope[0]), float(slope[1])))


def band_of(wavelength_nm: float) -> str:
    """The table a wavelength reads: "visible" at 550 nm, "nir" for 850-950 nm."""
    if wavelength_nm == VISIBLE_NM:
        return "visible"
    if 850.0 <= wavelength_nm <= 950.0:
        return "nir"
    raise ConfigError(
        f"wavelength_nm={wavelength_nm!r}: expected 850 to 950 nm (the drops' Mie table "
        "covers the near infrared of 905 nm LiDARs)"
    )


@dataclass(frozen=True)
class Optics:
    """A population of drops at one wavelength."""

    extinction_per_m: float  # alpha
    backscatter_per_m_sr: float  # beta
    backscatter_error: float  # beta's standard error from the table's sampling (1/(m sr))

    @property
    def lidar_ratio_sr(self) -> float:
        """S = alpha / beta."""
        return self.extinction_per_m / self.backscatter_per_m_sr


def _integrals(diameter_m: np.ndarray, weight: np.ndarray, wavelength_nm: float) -> Optics:
    """int w(D) (pi D^2 / 4) Q dD for Q_ext and Q_back / (4 pi) over a fine grid of diameters
    (``diameter_m`` increasing, ``weight`` the number density per metre of diameter there),
    by the trapezoid rule, each cell's efficiency its table mean; beta's standard error from
    the cells' (independent) sampling errors."""
    table = load_table(band_of(wavelength_nm))
    x = math.pi * diameter_m / (wavelength_nm * 1e-9)
    f = math.pi * diameter_m**2 / 4.0 * weight
    step = np.diff(diameter_m)
    # each grid point's share of the trapezoid sum, gathered by table cell
    share = np.zeros(len(diameter_m))
    share[:-1] += 0.5 * step * f[:-1]
    share[1:] += 0.5 * step * f[1:]
    per_cell = np.bincount(table.cell(x), share, minlength=len(table.q_ext))
    back = float(per_cell @ table.q_back) / (4.0 * math.pi)
    error = float(np.sqrt(np.sum((per_cell * table.q_back_error) ** 2))) / (4.0 * math.pi)
    return Optics(float(per_cell @ table.q_ext), back, error)


FOG_RADII_UM = np.geomspace(0.05, 80.0, 4000)  # where every fog distribution's mass lies


def fog_optics(fog: FogDistribution, visibility_m: float, wavelength_nm: float) -> Optics:
    """A fog's extinction alpha (1/m) and backscatter beta (1/(m sr)) at ``wavelength_nm``,
    its drops (distribution ``fog``) as many as make its extinction at 550 nm ln(20) / V."""
    if not visibility_m > 0.0:
        raise ConfigError(f"visibility_m={visibility_m!r}: expected positive metres")
    d_m = 2.0 * FOG_RADII_UM * 1e-6
    per_m = fog.density(FOG_RADII_UM) * 1e6 / 2.0 * 1e6  # per m^3 and metre of diameter
    visible = _integrals(d_m, per_m, VISIBLE_NM).extinction_per_m
    scale = math.log(20.0) / visibility_m / visible
    got = _integrals(d_m, per_m, wavelength_nm)
    return Optics(
        scale * got.extinction_per_m,
        scale * got.backscatter_per_m_sr,
        scale * got.backscatter_error,
    )


RAIN_DIAMETERS_MM = np.geomspace(0.01, 6.0, 4000)  # Marshall-Palmer drops to 6 mm


def rain_optics(atmosphere: Atmosphere, rate_mm_h: float, wavelength_nm: float) -> Optics:
    """A Marshall-Palmer rain's extinction alpha (1/m) and backscatter beta (1/(m sr)) at
    ``wavelength_nm``, rate R in mm/h (> 0)."""
    if not rate_mm_h > 0.0:
        raise ConfigError(f"rate_mm_h={rate_mm_h!r}: expected a positive rain rate")
    slope = atmosphere.rain_slope[0] * rate_mm_h ** atmosphere.rain_slope[1]
    d_mm = RAIN_DIAMETERS_MM
    per_m = atmosphere.rain_n0_per_m3_mm * np.exp(-slope * d_mm) * 1e3  # per m^3, m of D
    return _integrals(d_mm * 1e-3, per_m, wavelength_nm)


DEFAULT_FOG = "advection"  # the fog a visibility means unless said (choice: see water.toml)


@lru_cache(maxsize=256)
def fog_coefficients(visibility_m: float, wavelength_nm: float, fog: str = DEFAULT_FOG) -> Optics:
    """:func:`fog_optics` of the shipped fog ``fog`` (cached)."""
    return fog_optics(load_atmosphere().fogs[fog], visibility_m, wavelength_nm)


@lru_cache(maxsize=256)
def rain_coefficients(rate_mm_h: float, wavelength_nm: float) -> Optics:
    """:func:`rain_optics` of the shipped Marshall-Palmer rain (cached)."""
    return rain_optics(load_atmosphere(), rate_mm_h, wavelength_nm)
