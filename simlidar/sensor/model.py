"""Sensor models as data: a spinning multi-beam LiDAR described by a small TOML file.

A sensor file lives in ``sensors/`` (shipped in the wheel: ``vlp16``, ``hdl64e``, ``hdl32e``)
or anywhere on disk. It lists the beams in firing order (laser id order) with their elevation,
vertical offset and optional rotational correction, the firing timing, the rotation speeds the
sensor accepts, its range limits and resolution, and the rig (mount height, pitch); every value
is cited in the file. ``docs/sensor-model.md`` explains each key.

All values live in one frozen dataclass, :class:`Sensor`, stored as JSON in every dataset file.
Frame: x forward, y left, z up; the road surface is z = 0 and the sensor's rotation axis stands
at x = y = 0. Azimuth is measured clockwise from +x seen from above (the direction Velodyne
sensors spin), so positive azimuths look to the right.
"""

import math
from dataclasses import dataclass, fields, replace
from functools import lru_cache
from pathlib import Path

from simlidar.content import (
    PLAIN_NAME,
    PLAIN_NAME_RULE,
    check_keys,
    checked_text,
    content_dir,
    finite_number,
    key_error,
    read_named_toml,
    shipped_or_path,
)
from simlidar.errors import ConfigError, shown
from simlidar.scene.build import CELL_HALF_EXTENT_M
from simlidar.sensor.raycast import CELL_SPACING_M

SPEED_OF_LIGHT_M_PER_S = 299_792_458.0
DEFAULT_SENSOR = "vlp16"
MAX_BEAMS = 128
MAX_SENSOR_BYTES = 64 * 1024  # a sensor file is a few dozen lines
# What max_range_m and the emitters' height (mount_height_m and the largest vertical offset)
# may add up to, metres: the ray caster packs scenes into cells CELL_SPACING_M apart whose
# geometry extends CELL_HALF_EXTENT_M, and lets a ray run 1 m past max_range_m
# (simlidar.sensor.raycast.cast refuses more). The shipped sensors come to at most 121.7 m (the
# HDL-64E: 120 m from 1.73 m up).
MAX_REACH_M = CELL_SPACING_M - CELL_HALF_EXTENT_M - 1.0

# Keys added after dataset version 1.0.0, with the VLP-16's values: a sensor stores them only
# where its value differs (Sensor.to_dict), so that VLP-16 datasets keep their bytes; a stored
# sensor without them is read back with these values.
_LATER_KEYS = {
    "name": "vlp16",
    "model": "Velodyne VLP-16",
    "manual": "Velodyne LiDAR, VLP-16 User Manual, 63-9243 Rev D (2018)",
    "rot_corrections_deg": (),
    "firing_slots": (),
    "rpm_min": 300.0,
    "rpm_max": 1200.0,
    "rpm_step": 60.0,
}
_TUPLES = {"elevations_deg", "vertical_offsets_mm", "rot_corrections_deg", "firing_slots"}
_STRINGS = {"name", "model", "manual"}


@dataclass(frozen=True)
class Sensor:
    """A spinning multi-beam LiDAR. Per-beam tuples are in laser id order, which is the firing
    order; ``load_sensor`` builds one from a sensor file."""

    name: str  # the sensor file's stem; part of dataset names when not "vlp16"
    model: str  # maker and model, as the manual names it
    manual: str  # the document the values come from
    elevations_deg: tuple[float, ...]  # per laser id, positive up
    vertical_offsets_mm: tuple[float, ...]  # emitter height above the reference plane
    firing_interval_us: float  # between two consecutive firing slots
    cycle_us: float  # one firing cycle: every slot fired, then any recharge time
    rpm: float  # rotation speed
    rpm_min: float  # the speeds the sensor accepts: rpm_min..rpm_max in steps of rpm_step
    rpm_max: float
    rpm_step: float  # 0: any speed in the range
    min_range_m: float  # returns nearer than this are dropped
    max_range_m: float  # returns at this range or farther are dropped
    range_resolution_m: float  # the packet's distance step
    wavelength_nm: float  # informational
    mount_height_m: float  # rotation-axis reference plane above the road (the rig's)
    pitch_deg: float = 0.0  # forward tilt of the sensor; positive looks down (the rig's)
    # per laser id: beam azimuth = head azimuth - correction (Velodyne's calibration
    # `rotCorrection`, as its drivers apply it); empty: all zero
    rot_corrections_deg: tuple[float, ...] = ()
    # per laser id: the firing slot within a cycle (lasers sharing a slot fire together);
    # empty: slot = laser id (one laser at a time)
    firing_slots: tuple[int, ...] = ()

    def __post_init__(self) -> None:
        # the name is a file's stem, part of a dataset's folder name and printed in its card:
        # never a path (a dataset's stored sensor could say "../../etc/passwd")
        if not (isinstance(self.name, str) and PLAIN_NAME.match(self.name)):
            raise key_error("sensor", "name", f"a name of {PLAIN_NAME_RULE}", self.name)
        n = len(self.elevations_deg)
        if not 1 <= n <= MAX_BEAMS:
            raise ConfigError(
                f"elevations_deg: {n} beams: expected 1 to {MAX_BEAMS} elevations, one a laser"
            )
        for key in ("vertical_offsets_mm", "rot_corrections_deg", "firing_slots"):
            got = len(getattr(self, key))
            if got != n and (got or key == "vertical_offsets_mm"):
                raise ConfigError(
                    f"{key}: {got} values: expected {n}, one for each of the {n} elevations"
                )
        if not all(-90.0 < e < 90.0 for e in self.elevations_deg):
            raise ConfigError(
                f"elevations_deg={shown(list(self.elevations_deg))}: expected angles in (-90, 90)"
            )
        slots = self.slots
        if any(s < 0 or int(s) != s for s in slots):
            raise ConfigError(f"firing_slots={shown(list(slots))}: expected integers >= 0")
        firsts = list(dict.fromkeys(slots))  # the slots in the order their first laser comes
        if firsts != list(range(len(firsts))):
            raise ConfigError(
                f"firing_slots={shown(list(slots))}: beams out of order: expected the laser ids in "
                "firing order (the first laser of slot k before that of slot k + 1, no slot "
                "left out)"
            )
        if not self.firing_interval_us > 0.0:
            raise ConfigError(
                f"firing_interval_us={self.firing_interval_us}: expected a positive interval"
            )
        fired = (max(slots) + 1) * self.firing_interval_us
        if not self.cycle_us >= fired - 1e-9:
            raise ConfigError(
                f"cycle_us={self.cycle_us}: expected at least {fired:g} ({max(slots) + 1} "
                f"firing slots x firing_interval_us={self.firing_interval_us})"
            )
        if not 0.0 < self.rpm_min <= self.rpm_max or not self.rpm_step >= 0.0:
            raise ConfigError(
                f"rpm_min={self.rpm_min}, rpm_max={self.rpm_max}, rpm_step={self.rpm_step}: "
                "expected 0 < rpm_min <= rpm_max and rpm_step >= 0"
            )
        off_step = self.rpm_step and not math.isclose(
            (self.rpm - self.rpm_min) / self.rpm_step,
            round((self.rpm - self.rpm_min) / self.rpm_step),
            abs_tol=1e-9,
        )
        if not self.rpm_min <= self.rpm <= self.rpm_max or off_step:
            steps = f" in steps of {self.rpm_step:g}" if self.rpm_step else ""
            raise ConfigError(
                f"rpm={self.rpm}: expected {self.rpm_min:g} to {self.rpm_max:g}{steps} "
                f"({self.model}: {self.manual})"
            )
        if not self.cycle_us <= 60e6 / self.rpm:  # else a sweep's frame, a rotation, is empty
            raise ConfigError(
                f"cycle_us={self.cycle_us}: longer than a rotation at rpm={self.rpm} "
                f"({60e6 / self.rpm:.4g} us); expected at least one firing cycle a rotation"
            )
        if not 0.0 < self.min_range_m < self.max_range_m:
            raise ConfigError(
                f"range limits {self.min_range_m}..{self.max_range_m} m: expected "
                "0 < min_range_m < max_range_m"
            )
        if not self.mount_height_m > 0.0:
            raise ConfigError(f"mount_height_m={self.mount_height_m}: expected a positive height")
        offset_mm = max(abs(v) for v in self.vertical_offsets_mm)
        reach_m = self.max_range_m + self.mount_height_m + offset_mm * 1e-3
        if not reach_m < MAX_REACH_M:
            raise ConfigError(
                f"max_range_m={shown(self.max_range_m)}, mount_height_m="
                f"{shown(self.mount_height_m)}, vertical_offsets_mm up to {shown(offset_mm)}: "
                f"{reach_m:.4g} m in all; expected less than {MAX_REACH_M:g} m (a ray must end "
                "inside the ray caster's cell)"
            )
        if not -30.0 <= self.pitch_deg <= 30.0:
            raise ConfigError(f"pitch_deg={self.pitch_deg}: expected a value in [-30, 30]")
        if not self.wavelength_nm > 0.0:  # informational, but stored in every dataset
            raise ConfigError(
                f"wavelength_nm={self.wavelength_nm}: expected a positive wavelength in "
                "nanometres (903 for the VLP-16)"
            )
        if not self.range_resolution_m > 0.0:
            raise ConfigError(
                f"range_resolution_m={self.range_resolution_m}: expected a positive step"
            )

    @property
    def beams(self) -> int:
        """Lasers: the rows of a sample."""
        return len(self.elevations_deg)

    @property
    def slots(self) -> tuple[int, ...]:
        """Firing slot of each laser id (lasers sharing a slot fire at the same instant)."""
        return self.firing_slots or tuple(range(self.beams))

    @property
    def rotations(self) -> tuple[float, ...]:
        """Rotational correction of each laser id, degrees (zeros where the file gives none)."""
        return self.rot_corrections_deg or (0.0,) * self.beams

    @property
    def firing_times_us(self) -> tuple[float, ...]:
        """When each laser id fires, from the start of its firing cycle."""
        return tuple(s * self.firing_interval_us for s in self.slots)

    @property
    def degrees_per_us(self) -> float:
        """Rotation rate of the head."""
        return self.rpm / 60.0 * 360.0 * 1e-6

    @property
    def azimuth_step_deg(self) -> float:
        """Azimuth advance between two firing cycles (0.199 deg for a VLP-16 at 600 RPM)."""
        return self.degrees_per_us * self.cycle_us

    @property
    def firing_step_deg(self) -> float:
        """Azimuth advance between two consecutive firing slots inside a cycle."""
        return self.degrees_per_us * self.firing_interval_us

    @property
    def points_per_second(self) -> float:
        """Single-return point rate: every beam once a cycle (about 289,000 /s for a VLP-16)."""
        return self.beams / (self.cycle_us * 1e-6)

    @property
    def tof_max_ns(self) -> float:
        """Round-trip time of flight at maximum range: the delay normalisation constant."""
        return tof_ns(self.max_range_m)

    def to_dict(self) -> dict:
        """Plain-JSON form, as stored in every dataset file. Keys added after dataset version
        1.0.0 are left out where they hold the VLP-16's value (VLP-16 datasets keep their
        bytes)."""
        values = {}
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name in _LATER_KEYS and value == _LATER_KEYS[f.name]:
                continue
            values[f.name] = list(value) if isinstance(value, tuple) else value
        return values

    @classmethod
    def from_dict(cls, values: dict) -> "Sensor":
        """The inverse of :meth:`to_dict`, every key checked as a sensor file's: a ConfigError
        naming the key for anything else (a damaged or hostile dataset attribute)."""
        if not isinstance(values, dict):
            raise ConfigError(f"sensor {shown(values)}: expected an object of a sensor's keys")
        given = {**_LATER_KEYS, **values}
        name = given.pop("name")
        if not (isinstance(name, str) and PLAIN_NAME.match(name)):
            raise key_error("sensor", "name", f"a name of {PLAIN_NAME_RULE}", name)
        where = f"sensor {name!r}"
        checked = _checked(
            where, {k: list(v) if isinstance(v, tuple) else v for k, v in given.items()}
        )
        try:
            return cls(name=name, **checked)
        except ConfigError as exc:
            raise ConfigError(f"{where}: {exc}") from None

    def with_rpm(self, rpm: float) -> "Sensor":
        return replace(self, rpm=float(rpm))


def tof_ns(range_m):
    """Round-trip time of flight in nanoseconds for a target at ``range_m`` (array or float)."""
    return 2.0 * range_m / SPEED_OF_LIGHT_M_PER_S * 1e9


def row_order(sensor: Sensor) -> list[int]:
    """Laser ids sorted by elevation, highest first: row r of a sample is laser ``row_order[r]``
    (ties keep laser id order)."""
    return sorted(range(sensor.beams), key=lambda laser: -sensor.elevations_deg[laser])


def sensor_names() -> list[str]:
    """The shipped sensors' names."""
    return sorted(p.stem for p in content_dir("sensors").glob("*.toml"))


_FILE_KEYS = [f.name for f in fields(Sensor) if f.name != "name"]
_OPTIONAL = {"pitch_deg", "rot_corrections_deg", "firing_slots"}


def _checked(where: str, data: dict) -> dict:
    """The file's values with their types checked and numbers made floats (slots ints)."""
    check_keys(where, data, _FILE_KEYS, _OPTIONAL)
    values = {}
    for key, value in data.items():
        if key in _STRINGS:
            values[key] = checked_text(where, key, value)
        elif key == "firing_slots":
            if not isinstance(value, list) or not all(
                isinstance(v, int) and not isinstance(v, bool) for v in value
            ):
                raise key_error(where, key, "a list of integers", value)
            values[key] = tuple(value)
        elif key in _TUPLES:
            if not isinstance(value, list) or not all(finite_number(v) for v in value):
                raise key_error(where, key, "a list of finite numbers", value)
            values[key] = tuple(float(v) for v in value)
        else:
            if not finite_number(value):
                raise key_error(where, key, "a finite number", value)
            values[key] = float(value)
    return values


def load_sensor(name_or_path: str | Path) -> Sensor:
    """A shipped sensor by name, or a sensor file by path; every key checked.

    Raises ConfigError naming the file, the key and what was expected.
    """
    path = shipped_or_path(name_or_path, "sensors", "sensor")
    try:
        stamp = path.stat()
        stamp = (stamp.st_mtime_ns, stamp.st_size)
    except OSError:
        stamp = None
    return _load(str(path), stamp)


@lru_cache(maxsize=32)
def _load(text: str, stamp) -> Sensor:
    """The sensor of file ``text``, cached by path and (mtime, size) ``stamp``."""
    path = Path(text)
    where = f"sensor {path}"
    data = read_named_toml(path, where, MAX_SENSOR_BYTES)
    values = _checked(where, data)
    try:
        return Sensor(name=path.stem, **values)
    except ConfigError as exc:
        raise ConfigError(f"{where}: {exc}") from None


def default_sensor() -> Sensor:
    """The shipped VLP-16 (the paper's sensor)."""
    return load_sensor(DEFAULT_SENSOR)
