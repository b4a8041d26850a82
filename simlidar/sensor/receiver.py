"""The receiver as data: what turns a hit into a return a sensor would report (issue 41).

A receiver file lives in ``sensors/receivers/`` (``vlp16``, ``hdl64e``) and materials in
``scenes/materials.toml``; every value is cited in its file (sources quoted in
``docs/research/receiver-sources.md``). The functions here are pure numpy: the LiDAR range
equation, the detection threshold, the range noise, the reported reflectivity and fog extinction.
The generator uses them under a profile with a receiver (``sensor``, through
:mod:`simlidar.generator.returns`); the other profiles never do, and keep their bytes.
``docs/sensor-model.md`` ("Receiver") gives every formula with its source.
"""

import math
from dataclasses import asdict, dataclass, fields
from pathlib import Path

import numpy as np

from simlidar.content import (
    PLAIN_NAME,
    PLAIN_NAME_RULE,
    check_keys,
    checked_text,
    content_dir,
    finite_number,
    key_error,
    read_named_toml,
    read_toml,
    shipped_or_path,
)
from simlidar.errors import ConfigError, shown

MAX_RECEIVER_BYTES = 64 * 1024
MAX_MATERIALS_BYTES = 256 * 1024
RETURN_MODES = ("strongest", "last", "dual")
MATERIAL_KINDS = ("diffuse", "specular", "retroreflective")
# Koschmieder: visibility is the range at which a black target's contrast falls to 5 %
KOSCHMIEDER_CONTRAST = 0.05
# unsourced estimate: the Lambertian-equivalent gain reported as the top of the retro-reflector
# scale (the manual's "ideal reflection", 255): the top of materials.toml's retroreflector range
IDEAL_RETRO_GAIN = 50.0


@dataclass(frozen=True)
class Receiver:
    """A LiDAR's emitter and receiver; ``load_receiver`` builds one from a receiver file."""

    name: str  # the receiver file's stem (the sensor's name)
    model: str  # maker and model, as the manual names it
    manual: str  # the main document the values come from
    wavelength_nm: float  # laser wavelength
    pulse_width_ns: float  # emitted pulse length
    peak_power_w: float  # emitted peak power P_0
    divergence_h_mrad: float  # full-angle beam divergence along the scan (horizontal)
    divergence_v_mrad: float  # full-angle beam divergence across the scan (vertical)
    aperture_area_m2: float  # receiver aperture A_r
    optics_efficiency: float  # receiver optics' transmission eta, in (0, 1]
    threshold_w: float  # the weakest received power that is detected
    accuracy_m: float  # range noise (1 sigma) at the detection threshold
    rated_range_m: float  # the manual's maximum range ...
    rated_reflectance: float  # ... for a diffuse target of this reflectance
    return_modes: tuple[str, ...]  # of RETURN_MODES
    dual_when_strongest_is_last: str  # what dual mode reports beside the last return then
    reflectivity_diffuse_max: int = 0  # reported reflectivity of a 100 % diffuse target; 0: none
    reflectivity_max: int = 0  # reported reflectivity of an ideal retro-reflector; 0: none

    def __post_init__(self) -> None:
        # the name is a file's stem, printed in cards and errors: never a path (a dataset's
        # stored receiver could say "../../etc/passwd")
        if not (isinstance(self.name, str) and PLAIN_NAME.match(self.name)):
            raise key_error("receiver", "name", f"a name of {PLAIN_NAME_RULE}", self.name)
        where = f"receiver {self.name!r}"
        if not 200.0 <= self.wavelength_nm <= 2000.0:
            raise key_error(where, "wavelength_nm", "200 to 2000 nanometres", self.wavelength_nm)
        for key in ("pulse_width_ns", "peak_power_w", "aperture_area_m2", "threshold_w"):
            if not getattr(self, key) > 0.0:
                raise key_error(where, key, "a positive number", getattr(self, key))
        for key in ("divergence_h_mrad", "divergence_v_mrad"):
            if not 0.0 < getattr(self, key) <= 100.0:
                raise key_error(where, key, "0 to 100 milliradians", getattr(self, key))
        if not 0.0 < self.optics_efficiency <= 1.0:
            raise key_error(
                where, "optics_efficiency", "a number in (0, 1]", self.optics_efficiency
            )
        if not 0.0 < self.accuracy_m <= 1.0:
            raise key_error(where, "accuracy_m", "0 to 1 metre", self.accuracy_m)
        if not self.rated_range_m > 0.0:
            raise key_error(where, "rated_range_m", "a positive range", self.rated_range_m)
        if not 0.0 < self.rated_reflectance <= 1.0:
            raise key_error(
                where, "rated_reflectance", "a number in (0, 1]", self.rated_reflectance
            )
        if not self.return_modes or not set(self.return_modes) <= set(RETURN_MODES):
            raise key_error(
                where, "return_modes", f"a list of {list(RETURN_MODES)}", self.return_modes
            )
        if self.dual_when_strongest_is_last not in ("second_strongest", "first"):
            raise key_error(
                where,
                "dual_when_strongest_is_last",
                "'second_strongest' or 'first'",
                self.dual_when_strongest_is_last,
            )
        scale = (self.reflectivity_diffuse_max, self.reflectivity_max)
        if scale != (0, 0) and not 0 < scale[0] < scale[1] <= 255:
            raise key_error(
                where,
                "reflectivity_max",
                "0 < reflectivity_diffuse_max < reflectivity_max <= 255 (or neither key)",
                list(scale),
            )


@dataclass(frozen=True)
class Material:
    """A surface material at the LiDAR's wavelength (one table of ``scenes/materials.toml``)."""

    name: str  # the table's name
    kind: str  # of MATERIAL_KINDS
    reflectance: float  # nominal; Lambertian-equivalent gain for a retro-reflector (may be > 1)
    reflectance_min: float  # a sample draws its reflectance from min..max
    reflectance_max: float


_STRINGS = {"model", "manual", "dual_when_strongest_is_last"}
_INTS = {"reflectivity_diffuse_max", "reflectivity_max"}
_RECEIVER_KEYS = [f.name for f in fields(Receiver) if f.name != "name"]


def _receiver_values(where: str, data: dict) -> dict:
    """The file's values with their types checked: a ConfigError naming the key otherwise."""
    check_keys(where, data, _RECEIVER_KEYS, _INTS)
    values = {}
    for key, value in data.items():
        if key in _STRINGS:
            values[key] = checked_text(where, key, value)
        elif key == "return_modes":
            if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
                raise key_error(where, key, f"a list of {list(RETURN_MODES)}", value)
            values[key] = tuple(value)
        elif key in _INTS:
            if isinstance(value, bool) or not isinstance(value, int):
                raise key_error(where, key, "an integer", value)
            values[key] = value
        else:
            if not finite_number(value):
                raise key_error(where, key, "a finite number", value)
            values[key] = float(value)
    return values


def receiver_names() -> list[str]:
    """The shipped receivers' names (each a sensor of ``sensors/``)."""
    return sorted(p.stem for p in content_dir("sensors/receivers").glob("*.toml"))


def load_receiver(name_or_path: str | Path) -> Receiver:
    """A shipped receiver by sensor name (``"vlp16"``), or a receiver file by path; every key
    checked. Raises ConfigError naming the file, the key and what was expected."""
    path = shipped_or_path(name_or_path, "sensors/receivers", "receiver")
    where = f"receiver {path}"
    return checked_receiver(where, path.stem, read_named_toml(path, where, MAX_RECEIVER_BYTES))


def checked_receiver(where: str, name: str, data) -> Receiver:
    """The receiver ``name`` of a receiver file's keys ``data`` (also a receiver stored in a
    dataset, :func:`receiver_to_dict`), every key checked; a ConfigError starting with
    ``where``."""
    if not isinstance(data, dict):
        raise ConfigError(f"{where}: expected a table of {_RECEIVER_KEYS}, got {shown(data)}")
    values = _receiver_values(where, data)
    try:
        return Receiver(name=name, **values)
    except ConfigError as exc:
        raise ConfigError(f"{where}: {exc}") from None


def receiver_to_dict(receiver: Receiver) -> dict:
    """A receiver's keys as its file writes them, and its name (the inverse of
    :func:`checked_receiver`)."""
    return asdict(receiver) | {"return_modes": list(receiver.return_modes)}


def _material(where: str, name: str, table) -> Material:
    if not isinstance(table, dict):
        raise key_error(where, f"material.{name}", "a table", table)
    keys = {"kind", "reflectance", "reflectance_range"}
    for key in table:
        if key not in keys:
            raise key_error(where, f"material.{name}.{key}", f"one of {sorted(keys)}", key)
    for key in sorted(keys - table.keys()):
        raise ConfigError(f"{where}: key 'material.{name}.{key}' is missing")
    kind, nominal, span = table["kind"], table["reflectance"], table["reflectance_range"]
    if kind not in MATERIAL_KINDS:
        raise key_error(where, f"material.{name}.kind", f"one of {list(MATERIAL_KINDS)}", kind)
    if not finite_number(nominal):
        raise key_error(where, f"material.{name}.reflectance", "a finite number", nominal)
    if not (isinstance(span, list) and len(span) == 2 and all(map(finite_number, span))):
        raise key_error(where, f"material.{name}.reflectance_range", "[min, max]", span)
    low, high = float(span[0]), float(span[1])
    top = math.inf if kind == "retroreflective" else 1.0
    if not 0.0 < low <= nominal <= high <= top:
        bound = "" if kind == "retroreflective" else " <= 1 (a fraction, not a percentage)"
        raise key_error(
            where,
            f"material.{name}.reflectance",
            f"0 < min <= reflectance <= max{bound}",
            [low, nominal, high],
        )
    return Material(name, kind, float(nominal), low, high)


def load_materials(path: str | Path | None = None) -> tuple[dict[str, Material], dict]:
    """The materials of ``scenes/materials.toml`` (or of the file ``path``) by name, and the
    surfaces table (catalog surface label: the material names a sample draws from). Raises
    ConfigError naming the file and the key."""
    path = Path(path) if path is not None else content_dir("scenes") / "materials.toml"
    where = f"materials {path}"
    return checked_materials(where, read_toml(path, MAX_MATERIALS_BYTES, ConfigError, where))


def checked_materials(where: str, data) -> tuple[dict[str, Material], dict]:
    """The materials and surfaces of a materials file's content ``data`` (also one stored in a
    dataset, :func:`materials_to_dict`), every key checked; a ConfigError starting with
    ``where``."""
    if not isinstance(data, dict):
        raise ConfigError(f"{where}: expected tables 'material' and 'surfaces', got {shown(data)}")
    for key in data:
        if key not in ("material", "surfaces"):
            raise key_error(where, key, "'material' or 'surfaces'", key)
    tables = data.get("material")
    if not isinstance(tables, dict) or not tables:
        raise key_error(where, "material", "tables [material.<name>]", tables)
    materials = {name: _material(where, name, table) for name, table in tables.items()}
    surfaces = data.get("surfaces", {})
    if not isinstance(surfaces, dict):
        raise key_error(where, "surfaces", "a table of surface = [materials]", surfaces)
    for surface, names in surfaces.items():
        if not isinstance(names, list) or not names or not set(names) <= materials.keys():
            raise key_error(where, f"surfaces.{surface}", f"a list of {sorted(materials)}", names)
    return materials, surfaces


def materials_to_dict(materials: dict[str, Material], surfaces: dict) -> dict:
    """Materials and surfaces as a materials file writes them (the inverse of
    :func:`checked_materials`)."""
    tables = {
        m.name: {
            "kind": m.kind,
            "reflectance": m.reflectance,
            "reflectance_range": [m.reflectance_min, m.reflectance_max],
        }
        for m in materials.values()
    }
    return {"material": tables, "surfaces": surfaces}


def received_power_w(
    receiver: Receiver, range_m, reflectance, incidence_rad=0.0, extinction_per_m=0.0
):
    """Received peak power for an extended Lambertian target that fills the beam, by the LiDAR
    range equation (Rasshofer et al. 2011; the hard target of Hahner et al., ICCV 2021)::

        P_r = P_0 * rho * cos(theta) * A_r * eta * exp(-2 * alpha * R) / (pi * R^2)

    All arguments broadcast (any shape); returns watts in their broadcast shape.

    receiver : the emitter and receiver: P_0 (``peak_power_w``), A_r (``aperture_area_m2``) and
        eta (``optics_efficiency``)
    range_m : R, the target's range in metres (> 0: the power divides by R^2)
    reflectance : rho, the target's diffuse reflectance
    incidence_rad : theta, the angle between the beam and the surface's normal in radians
        (0: normal incidence); cos(theta) is taken as 0 beyond 90 degrees
    extinction_per_m : alpha, the atmosphere's extinction coefficient in 1/m (0: clear air)
    """
    range_m = np.asarray(range_m, dtype=float)
    cosine = np.clip(np.cos(incidence_rad), 0.0, None)
    constant = receiver.peak_power_w * receiver.aperture_area_m2 * receiver.optics_efficiency
    transmission = np.exp(-2.0 * np.asarray(extinction_per_m, dtype=float) * range_m)
    return constant * np.asarray(reflectance) * cosine * transmission / (math.pi * range_m**2)


def detected(receiver: Receiver, power_w):
    """Whether each received power reaches the detection threshold (bool, power's shape)."""
    return np.asarray(power_w) >= receiver.threshold_w


def max_range_m(receiver: Receiver, reflectance, incidence_rad=0.0, extinction_per_m=0.0):
    """The range at which ``received_power_w`` falls to the threshold (broadcast shape).

    Without extinction it is closed-form, R = sqrt(P_0 rho cos(theta) A_r eta / (pi P_th)), so
    it scales as sqrt(reflectance); with extinction alpha, R^2 exp(2 alpha R) = R_0^2 is solved
    by bisection in [0, R_0] (R_0: the range without extinction).
    """
    constant = receiver.peak_power_w * receiver.aperture_area_m2 * receiver.optics_efficiency
    cosine = np.clip(np.cos(incidence_rad), 0.0, None)
    free_m = np.sqrt(constant * np.asarray(reflectance) * cosine / (math.pi * receiver.threshold_w))
    alpha = np.asarray(extinction_per_m, dtype=float)
    free_m, alpha = np.broadcast_arrays(free_m, alpha)
    low, high = np.zeros_like(free_m), free_m.copy()
    for _ in range(64):  # 2^-64 of R_0: far below a millimetre
        mid = 0.5 * (low + high)
        reached = mid**2 * np.exp(2.0 * alpha * mid) <= free_m**2
        low, high = np.where(reached, mid, low), np.where(reached, high, mid)
    return low if low.ndim else float(low)


def range_noise_m(receiver: Receiver, power_w):
    """Range noise (1 sigma, metres) of a return of ``power_w``: sigma grows as 1/sqrt(SNR),
    the law LISA uses (Kilic et al. 2021, ``sig = dR / sqrt(2 * snr)`` with snr = P / P_min),
    anchored so that sigma is the manual's accuracy at the threshold (calibrated: the accuracy
    is read as the worst case within the rated range)::

        sigma = accuracy_m * sqrt(P_th / P)

    Infinite where the power is not positive; power's shape."""
    power_w = np.asarray(power_w, dtype=float)
    positive = power_w > 0.0
    sigma = receiver.accuracy_m * np.sqrt(receiver.threshold_w / np.where(positive, power_w, 1.0))
    return np.where(positive, sigma, np.inf)


def reflectivity_byte(receiver: Receiver, reflectance, retroreflective=False):
    """The calibrated reflectivity a receiver reports for a return (uint8, the arguments'
    broadcast shape). VLP-16 manual sec. 6.1 p. 32: "Diffuse reflectors report values from 0 to
    100 for reflectivities from 0% to 100%" (here ``round(reflectivity_diffuse_max * rho)``,
    clipped to the diffuse scale); "Retroreflectors report values from 101 to 255, where 255
    represents an ideal reflection" (here 101 at gain 1 to 255 at ``IDEAL_RETRO_GAIN``,
    linear in log gain: unsourced estimate, the manual gives no curve). A ConfigError for a
    receiver without a scale."""
    low, top = receiver.reflectivity_diffuse_max, receiver.reflectivity_max
    if low == 0:
        raise ConfigError(
            f"receiver {receiver.name!r}: no reflectivity scale (reflectivity_diffuse_max); "
            "expected a receiver whose manual defines one"
        )
    rho = np.asarray(reflectance, dtype=float)
    diffuse = np.clip(np.round(low * rho), 0, low)
    gain = np.log(np.clip(rho, 1.0, IDEAL_RETRO_GAIN)) / math.log(IDEAL_RETRO_GAIN)
    retro = low + 1 + np.round((top - low - 1) * gain)
    return np.where(retroreflective, retro, diffuse).astype(np.uint8)


def koschmieder_extinction_per_m(visibility_m):
    """Atmospheric extinction alpha (1/m) from the meteorological visibility V (m) by
    Koschmieder's law, alpha = -ln(0.05) / V = ln(20) / V ~= 3.0 / V (as Hahner et al. 2021
    write it: ``mor = np.log(20) / alpha``). Visibility's shape; a ConfigError for V <= 0."""
    visibility_m = np.asarray(visibility_m, dtype=float)
    if not np.all(visibility_m > 0.0):
        raise ConfigError(f"visibility_m={visibility_m.tolist()}: expected positive metres")
    alpha = -math.log(KOSCHMIEDER_CONTRAST) / visibility_m
    return alpha if alpha.ndim else float(alpha)
