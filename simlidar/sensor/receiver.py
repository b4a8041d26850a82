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
    # the detector's noise (issue 62; simlidar.sensor.detection); 0: a deterministic threshold
    noise_w: float = 0.0  # sigma_0, dark and amplifier noise referred to the optical input
    responsivity_a_w: float = 0.0  # R_0 (0: no shot noise)
    excess_noise: float = 0.0  # F of the APD
    bandwidth_hz: float = 0.0  # B, the receiver's noise bandwidth
    filter_nm: float = 0.0  # the optical filter's width (sunlight's background)
    field_sr: float = 0.0  # the receiver's field of view (sunlight's background)
    ambient_w_m2_nm: float = 0.0  # solar spectral irradiance at the wavelength (0: night)
    # the biaxial overlap of beam and receiver (issue 62); 0: every range seen whole
    separation_m: float = 0.0  # between the transmitter's and the receiver's axes
    receiver_opening_deg: float = 0.0  # the receiver's full field angle

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
        for key in NOISE_KEYS + OVERLAP_KEYS:
            value = getattr(self, key)
            if not (math.isfinite(value) and value >= 0.0):
                raise key_error(where, key, "a number >= 0 (0: not modelled)", value)
        if self.noise_w > 0.0 and self.shot_noise and self.excess_noise < 1.0:
            raise key_error(where, "excess_noise", "F >= 1 with shot noise", self.excess_noise)
        if (self.separation_m > 0.0) != (self.receiver_opening_deg > 0.0):
            raise key_error(
                where,
                "receiver_opening_deg",
                "both separation_m and receiver_opening_deg, or neither",
                [self.separation_m, self.receiver_opening_deg],
            )
        scale = (self.reflectivity_diffuse_max, self.reflectivity_max)
        if scale != (0, 0) and not 0 < scale[0] < scale[1] <= 255:
            raise key_error(
                where,
                "reflectivity_max",
                "0 < reflectivity_diffuse_max < reflectivity_max <= 255 (or neither key)",
                list(scale),
            )

    @property
    def shot_noise(self) -> bool:
        """Whether the signal's and sunlight's shot noise is modelled."""
        return self.responsivity_a_w > 0.0 and self.bandwidth_hz > 0.0

    def detector(self):
        """The receiver's noise as a :class:`simlidar.sensor.detection.Detector` (None
        without ``noise_w``)."""
        from simlidar.sensor.detection import Detector

        if self.noise_w == 0.0:
            return None
        if not self.shot_noise:  # no shot noise: sigma = sigma_0 at every power
            return Detector(1.0, 1.0, 1.0, self.noise_w, 1.0, 1.0, shot=False)
        return Detector(
            self.responsivity_a_w,
            self.excess_noise,
            self.bandwidth_hz,
            self.noise_w,
            self.filter_nm or 1.0,
            self.field_sr or 1.0,
        )


NOISE_KEYS = (
    "noise_w",
    "responsivity_a_w",
    "excess_noise",
    "bandwidth_hz",
    "filter_nm",
    "field_sr",
    "ambient_w_m2_nm",
)
OVERLAP_KEYS = ("separation_m", "receiver_opening_deg")


@dataclass(frozen=True)
class Material:
    """A surface material at the LiDAR's wavelength (one table of ``scenes/materials.toml``)."""

    name: str  # the table's name
    kind: str  # of MATERIAL_KINDS
    reflectance: float  # nominal; Lambertian-equivalent gain for a retro-reflector (may be > 1)
    reflectance_min: float  # a sample draws its reflectance from min..max
    reflectance_max: float
    # how its return falls with incidence (issue 62; simlidar.sensor.angle_laws)
    angle_law: str = "lambert"
    roughness_deg: float = 0.0  # sigma of "oren_nayar"
    exponent: float = 1.0  # n of "retroreflective"
    specular: float = 0.0  # rho_s of a glossy coat's Ward lobe (0: none) ...
    lobe_deg: float = 0.0  # ... and its width a

    def angle_factor(self, cos_incidence):
        """f(theta) of this material's law at |cos(theta)| ``cos_incidence`` (its coat's lobe
        apart: ``specular`` x :func:`simlidar.sensor.angle_laws.specular_factor`)."""
        from simlidar.sensor.angle_laws import angle_factor

        return angle_factor(self.angle_law, cos_incidence, self.roughness_deg, self.exponent)


_ANGLE_DEFAULTS = {
    "angle_law": "lambert",
    "roughness_deg": 0.0,
    "exponent": 1.0,
    "specular": 0.0,
    "lobe_deg": 0.0,
}


_STRINGS = {"model", "manual", "dual_when_strongest_is_last"}
_INTS = {"reflectivity_diffuse_max", "reflectivity_max"}
_RECEIVER_KEYS = [f.name for f in fields(Receiver) if f.name != "name"]
_OPTIONAL = _INTS | set(NOISE_KEYS) | set(OVERLAP_KEYS)


def _receiver_values(where: str, data: dict) -> dict:
    """The file's values with their types checked: a ConfigError naming the key otherwise."""
    check_keys(where, data, _RECEIVER_KEYS, _OPTIONAL)
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
    values = asdict(receiver) | {"return_modes": list(receiver.return_modes)}
    # a key not modelled (0) is left out, so a receiver without them stores as before
    return {k: v for k, v in values.items() if k not in _OPTIONAL - _INTS or v != 0.0}


def _material(where: str, name: str, table) -> Material:
    if not isinstance(table, dict):
        raise key_error(where, f"material.{name}", "a table", table)
    required = {"kind", "reflectance", "reflectance_range"}
    keys = required | _ANGLE_DEFAULTS.keys()
    for key in table:
        if key not in keys:
            raise key_error(where, f"material.{name}.{key}", f"one of {sorted(keys)}", key)
    for key in sorted(required - table.keys()):
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
    law = _angle_law(where, name, table)
    return Material(name, kind, float(nominal), low, high, **law)


def _angle_law(where: str, name: str, table: dict) -> dict:
    """A material's angle-law keys, checked (defaults: Lambert, no coat)."""
    from simlidar.sensor.angle_laws import ANGLE_LAWS

    values = {k: table.get(k, v) for k, v in _ANGLE_DEFAULTS.items()}
    if values["angle_law"] not in ANGLE_LAWS:
        raise key_error(
            where, f"material.{name}.angle_law", f"one of {list(ANGLE_LAWS)}", values["angle_law"]
        )
    bounds = {
        "roughness_deg": (0.0, 90.0),
        "exponent": (0.0, 100.0),
        "specular": (0.0, 1.0),
        "lobe_deg": (0.0, 45.0),
    }
    for key, (low, high) in bounds.items():
        value = values[key]
        if not (finite_number(value) and low <= value <= high):
            raise key_error(where, f"material.{name}.{key}", f"a number in [{low}, {high}]", value)
        values[key] = float(value)
    if (values["specular"] > 0.0) != (values["lobe_deg"] > 0.0):
        raise key_error(
            where,
            f"material.{name}.lobe_deg",
            "a lobe width with a specular coat, and neither without one",
            [values["specular"], values["lobe_deg"]],
        )
    return values


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
    tables = {}
    for m in materials.values():
        tables[m.name] = {
            "kind": m.kind,
            "reflectance": m.reflectance,
            "reflectance_range": [m.reflectance_min, m.reflectance_max],
        }
        # a law's key at its default is left out, so a Lambertian file stores as before
        for key, default in _ANGLE_DEFAULTS.items():
            if getattr(m, key) != default:
                tables[m.name][key] = getattr(m, key)
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


def crossover_ranges(receiver: Receiver) -> tuple[float, float] | None:
    """r_1, r_2 of the receiver's biaxial geometry (None where it has none): the beam (its
    larger full divergence) enters the receiver's field (``receiver_opening_deg``) at r_1 and
    lies wholly inside it from r_2, for axes ``separation_m`` apart and apertures of the
    receiver's area (Hahner et al. 2021's R_1, R_2 formulas, their ``theory.py``; both
    apertures taken as the receiver's)."""
    if receiver.separation_m == 0.0:
        return None
    radius = math.sqrt(receiver.aperture_area_m2 / math.pi)
    tan_t = math.tan(0.5e-3 * max(receiver.divergence_h_mrad, receiver.divergence_v_mrad))
    tan_r = math.tan(math.radians(receiver.receiver_opening_deg) / 2.0)
    if not tan_r > tan_t:
        raise ConfigError(
            f"receiver {receiver.name!r}: receiver_opening_deg={receiver.receiver_opening_deg!r} "
            "is narrower than the beam: expected a field wider than the divergence"
        )
    r_1 = max(0.0, (receiver.separation_m - 2.0 * radius) / (tan_t + tan_r))
    r_2 = receiver.separation_m / (tan_r - tan_t)
    return r_1, r_2


def signal_noise_w(receiver: Receiver, power_w, reflectance=0.0):
    """sigma (W) of the noise on a received power (any shape): the detector's own, and the
    shot noise of the signal and of the sunlight a scene of ``reflectance`` (rho f(theta),
    the hit's; 0: sky) sends into the field of view (:mod:`simlidar.sensor.detection`); 0
    without ``noise_w``."""
    from simlidar.sensor.detection import background_w, noise_w

    detector = receiver.detector()
    if detector is None:
        return np.zeros(np.shape(power_w))
    back = background_w(
        detector,
        receiver.ambient_w_m2_nm,
        reflectance,
        receiver.aperture_area_m2,
        receiver.optics_efficiency,
    )
    return noise_w(detector, power_w, back)


def timing_noise_m(receiver: Receiver, power_w, sigma_w):
    """Range noise (1 sigma, m) of a return of ``power_w`` measured with noise ``sigma_w``:
    the timing jitter of a pulse's edge, noise over slope (the textbook relation sigma_t =
    sigma_n / (dV/dt), e.g. Spieler, *Semiconductor Detector Systems*, Oxford 2005, on timing
    measurements; not read here), for the Gaussian pulse's steepest
    slope S / (sigma_p sqrt(e)), sigma_t = sigma_p sqrt(e) sigma / S, in quadrature with the
    manual's accuracy as the floor (calibrated: the accuracy read as what remains at high
    SNR)::

        sigma_R = sqrt(accuracy^2 + (c sigma_t / 2)^2)

    Infinite where the power is not positive; the arguments' broadcast shape."""
    from simlidar.sensor.waveform import pulse_sigma_ns

    power = np.asarray(power_w, dtype=float)
    positive = power > 0.0
    sigma_t_ns = (
        pulse_sigma_ns(receiver.pulse_width_ns)
        * math.sqrt(math.e)
        * np.asarray(sigma_w)
        / np.where(positive, power, 1.0)
    )
    jitter_m = 0.5 * 0.299792458 * sigma_t_ns
    return np.where(positive, np.sqrt(receiver.accuracy_m**2 + jitter_m**2), np.inf)


def apparent_reflectance(receiver: Receiver, power_w, range_m):
    """The reflectance a return's power reads as, compensated for range as a unit calibrates
    its intensity (not for incidence or the air, which it cannot know): P pi R^2 / (P_0 A_r
    eta); broadcast shape."""
    constant = receiver.peak_power_w * receiver.aperture_area_m2 * receiver.optics_efficiency
    return np.asarray(power_w, dtype=float) * math.pi * np.asarray(range_m) ** 2 / constant
