"""The Velodyne VLP-16 as its user manual (63-9243 Rev D) gives it.

All values live in one frozen dataclass, :class:`VLP16`, whose fields are stored in every
dataset file. Frame: x forward, y left, z up; the road surface is z = 0 and the sensor's
rotation axis stands at x = y = 0. Azimuth is measured clockwise from +x seen from above
(the direction the VLP-16 spins), so positive azimuths look to the right.
"""

from dataclasses import asdict, dataclass

from simlidar.errors import ConfigError

SPEED_OF_LIGHT_M_PER_S = 299_792_458.0

# Laser ids 0..15 in firing order (manual, Table 9-1; ROS velodyne driver VLP16db.yaml).
ELEVATIONS_DEG = (-15.0, 1.0, -13.0, 3.0, -11.0, 5.0, -9.0, 7.0,
                  -7.0, 9.0, -5.0, 11.0, -3.0, 13.0, -1.0, 15.0)  # fmt: skip
# Vertical offset of each laser's emitter from the sensor's reference plane, millimetres.
VERTICAL_OFFSETS_MM = (11.2, -0.7, 9.7, -2.2, 8.1, -3.7, 6.6, -5.1,
                       5.1, -6.6, 3.7, -8.1, 2.2, -9.7, 0.7, -11.2)  # fmt: skip


@dataclass(frozen=True)
class VLP16:
    """Sensor parameters. Defaults are the manual's; mount height and pitch are the rig's."""

    elevations_deg: tuple[float, ...] = ELEVATIONS_DEG  # per laser id, firing order
    vertical_offsets_mm: tuple[float, ...] = VERTICAL_OFFSETS_MM  # per laser id
    firing_interval_us: float = 2.304  # between two consecutive laser firings
    cycle_us: float = 55.296  # 16 firings (36.864 us) + 18.432 us recharge
    rpm: float = 600.0  # rotation speed, 300..1200 in steps of 60 per the manual
    min_range_m: float = 1.0  # returns nearer than this are dropped
    max_range_m: float = 100.0  # returns at this range or farther are dropped
    range_resolution_m: float = 0.002  # the packet encodes distance in 2 mm steps
    wavelength_nm: float = 903.0  # informational
    mount_height_m: float = 1.8  # rotation-axis reference plane above the road (roof rack)
    pitch_deg: float = 0.0  # forward tilt of the sensor; positive looks down

    def __post_init__(self) -> None:
        if len(self.elevations_deg) != 16 or len(self.vertical_offsets_mm) != 16:
            raise ConfigError(
                f"sensor needs 16 elevations and 16 vertical offsets, got "
                f"{len(self.elevations_deg)} and {len(self.vertical_offsets_mm)}"
            )
        if not 300.0 <= self.rpm <= 1200.0 or self.rpm % 60:
            raise ConfigError(
                f"rpm={self.rpm}: expected 300 to 1200 in steps of 60 (VLP-16 manual 63-9243 "
                "Rev D, p. 50: other settings break motor speed control and phase lock)"
            )
        if not 0.0 < self.min_range_m < self.max_range_m:
            raise ConfigError(
                f"range limits {self.min_range_m}..{self.max_range_m} m: expected "
                "0 < min_range_m < max_range_m"
            )
        if not self.mount_height_m > 0.0:
            raise ConfigError(f"mount_height_m={self.mount_height_m}: expected a positive height")
        if not -30.0 <= self.pitch_deg <= 30.0:
            raise ConfigError(f"pitch_deg={self.pitch_deg}: expected a value in [-30, 30]")
        if not self.range_resolution_m > 0.0:
            raise ConfigError(
                f"range_resolution_m={self.range_resolution_m}: expected a positive step"
            )

    @property
    def degrees_per_us(self) -> float:
        """Rotation rate of the head."""
        return self.rpm / 60.0 * 360.0 * 1e-6

    @property
    def azimuth_step_deg(self) -> float:
        """Azimuth advance between two firing cycles (0.199 deg at 600 RPM)."""
        return self.degrees_per_us * self.cycle_us

    @property
    def firing_step_deg(self) -> float:
        """Azimuth advance between two consecutive laser firings inside a cycle."""
        return self.degrees_per_us * self.firing_interval_us

    @property
    def points_per_second(self) -> float:
        """Single-return point rate: 16 firings per cycle (about 289,000 /s)."""
        return 16.0 / (self.cycle_us * 1e-6)

    @property
    def tof_max_ns(self) -> float:
        """Round-trip time of flight at maximum range: the delay normalisation constant."""
        return tof_ns(self.max_range_m)

    def to_dict(self) -> dict:
        """Plain-JSON form, as stored in every dataset file."""
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}

    @classmethod
    def from_dict(cls, values: dict) -> "VLP16":
        fields = {k: tuple(v) if isinstance(v, list) else v for k, v in values.items()}
        return cls(**fields)


def tof_ns(range_m):
    """Round-trip time of flight in nanoseconds for a target at ``range_m`` (array or float)."""
    return 2.0 * range_m / SPEED_OF_LIGHT_M_PER_S * 1e9


def row_order(sensor: VLP16) -> list[int]:
    """Laser ids sorted by elevation, highest first: row r of a sample is laser ``row_order[r]``."""
    return sorted(range(16), key=lambda laser: -sensor.elevations_deg[laser])
