"""The generator's configuration: one frozen dataclass, stored as JSON in every split file."""

import json
import math
from dataclasses import asdict, dataclass, fields, replace

from simlidar.content import key_error
from simlidar.dataset.storage import MAX_CHUNK_BYTES
from simlidar.errors import ConfigError, shown
from simlidar.generator.profiles import PHYSICAL_RULE, Profile, checked_profile
from simlidar.motion.poses import PlanarMotion
from simlidar.motion.trajectory import Trajectory
from simlidar.sensor.footprint import MAX_RINGS
from simlidar.sensor.model import Sensor, default_sensor
from simlidar.sensor.rays import scan_window_ns
from simlidar.sensor.receiver import RETURN_MODES
from simlidar.sensor.waveform import BIN_NS
from simlidar.sensor.weather import MAX_RAIN_MM_H
from simlidar.settings import Choice, Range, check, setting

MAX_WAVEFORM_BIN_NS = 4.0
# The ego's motion: up to 70 m/s (252 km/h, past any road's limit; the objects' own bound,
# simlidar.scene.motion.KEYS) and half a turn a second (a car at its tightest turns about
# 115 deg/s: 5 m radius at 10 m/s)
MAX_SPEED_MPS = 70.0
MAX_YAW_RATE_DEG_S = 180.0

MAX_SPLIT_SIZE = 10**9  # samples per split
TIMINGS = ("flash", "scan")
SIZE = Range(1, MAX_SPLIT_SIZE, "an integer")


def check_window(config, noun: str) -> None:
    """What a window's configuration (a GeneratorConfig, a StreamConfig) must satisfy besides
    its fields' rules, which this checks too: splits of at least one ``noun`` a class (before the
    rules: a better message), and columns no closer than the sensor's firing cycles."""
    for name in ("train_size", "test_size"):
        value = getattr(config, name)
        classes = config.classes if SIZE.accepts(config.classes) else SIZE.low
        if not SIZE.accepts(value) or value < classes:
            raise ConfigError(
                f"{name}={value!r}: expected an integer in [{classes}, {MAX_SPLIT_SIZE}] (at "
                f"least one {noun} of every class: classes are balanced)"
            )
    check(config)
    sensor, width, fov = config.sensor, config.width, config.fov_deg
    step = sensor.azimuth_step_deg
    if fov / width < step * (1.0 - 1e-9):
        # a column takes the cycle nearest its centre: closer columns would share firings
        raise ConfigError(
            f"width={width}: columns {fov / width:.4g} deg apart, closer than the {step:.4g} "
            f"deg between the firing cycles of sensor {sensor.name} at {sensor.rpm:g} RPM; "
            f"expected at most {int(fov / step + 1e-9)} columns over {fov:g} deg (each column "
            "its own firing)"
        )


@dataclass(frozen=True)
class GeneratorConfig:
    """Everything that decides a dataset's bytes (with the scene catalog and the version)."""

    classes: int = setting(
        32, "32: layout x object, 8: layout alone, 4: object alone.", Range(2, None, "an integer")
    )
    noise: float = setting(0.2, "Noise level a of U(0, a), added to every normalised delay.",
                           Range(0, 1, "a level"))  # fmt: skip
    train_size: int = setting(3000, "Samples in train.h5 (the paper's 3000).", SIZE)
    test_size: int = setting(600, "Samples in test.h5 (the paper's 600).", SIZE)
    seed: int = setting(
        0,
        "Root of every random stream (numpy SeedSequence).",
        Range(0, 2**63, "an integer", high_open=True),
    )
    width: int = setting(16, "Azimuth columns per sample.", Range(1, 1024, "an integer"))
    fov_deg: float = setting(
        36.0,
        "Horizontal field of view of the columns, centred ahead, degrees.",
        Range(0, 180, "degrees", low_open=True, high_open=True),
    )
    min_object_hits: int = setting(
        4, "A labelled object is hit by at least this many pulses.", Range(1, None, "an integer")
    )
    max_attempts: int = setting(
        200, "Scene redraws allowed per sample before giving up.", Range(1, None, "an integer")
    )
    shift_max: float = setting(
        0.0,
        "Delay-shift augmentation: every return of a sample moves by U(-s, s).",
        Range(0, 1, "a value", high_open=True),
    )
    # stored only when not 1, so the files of datasets made before the option existed stay
    # byte for byte the same
    variation: float = setting(
        1.0,
        "Scene variation: every parameter range of the scene catalog shrunk around its centre "
        "by this factor (1: the recipes as written).",
        Range(0, 1, "a factor", low_open=True, note="(1: the scene catalog's ranges as written)"),
    )
    sensor: Sensor = setting(
        help="The sensor model (a file of sensors/, simlidar.sensor.load_sensor).",
        default_factory=default_sensor,
    )
    # stored only when "scan", so that flash datasets keep their bytes (as variation above)
    timing: str = setting(
        "flash",
        "What a pulse's delay measures: flash, its time of flight (every pulse of a window "
        "leaves at once: the paper's); scan, its arrival time in the sweep, emission (firing "
        "order, cycle, column) plus time of flight (docs/sensor-model.md).",
        Choice(TIMINGS),
    )
    # None: the physical rule of dataset version 1.0.0 (stored only when not None, for the
    # same reason as variation). `variation` and `shift_max` above are the values used, which
    # start from the profile's and may be overridden (docs/profiles.md)
    profile: Profile | None = setting(
        None, "The dataset profile (simlidar.generator.profiles) whose pulse rule pixels follow."
    )

    # stored only when finite, so that clear-air datasets keep their bytes (as timing above)
    fog_visibility_m: float = setting(
        math.inf,
        "Fog, by its meteorological visibility in metres: every pulse loses power to two-way "
        "Beer-Lambert extinction exp(-2 alpha R), so weaker returns drop below the receiver's "
        "threshold, and the fog's own backscatter joins each pulse's waveform, so near false "
        "returns appear; both from Mie theory over an advection fog's drops, as many as make "
        "Koschmieder's ln(20) / V in visible light (at 903 nm alpha = 1.01 ln(20) / V, beta = "
        "0.170 / V per m and sr; docs/sensor-model.md); a profile with a receiver only (sensor).",
        Range(0, None, "metres", low_open=True, note="(inf: clear air)"),
    )
    # stored only when > 0, so that datasets without rain keep their bytes (as above)
    rain_rate_mm_h: float = setting(
        0.0,
        "Rain, by its rate in mm/h (after LISA, Kilic et al. 2021): drops of the Marshall-Palmer "
        "size distribution take power from every pulse by two-way extinction (Mie's, alpha = "
        "1.56e-3 per m at 10 mm/h) and the drops in a beam echo (water's Fresnel reflectance "
        "times the share of the beam a drop covers), so near false returns appear; a profile "
        "with a receiver only (sensor).",
        Range(0, MAX_RAIN_MM_H, "mm/h", note="(0: no rain)"),
    )
    # stored only when not 1 / strongest, so that the sensor profile's datasets made before
    # them keep their bytes (as fog_visibility_m above)
    beam_samples: int = setting(
        1,
        "Beam footprint: the beam sampled by this many rings of sub-rays over the receiver's "
        "divergence, 1 + 3 Q (Q - 1) rays a pulse (HELIOS++'s beamSampleQuality; 1: one ray "
        "along the axis, 2: 7, 3: 19), whose echoes make the pulse's waveform and returns; a "
        "profile with a receiver only (sensor).",
        Range(1, MAX_RINGS, "an integer", note="(1: one ray a pulse)"),
    )
    # stored only when not 0, for the same reason
    waveform_bin_ns: float = setting(
        0.0,
        "Store each pulse's received waveform (dataset `waveform`, watts, float32) sampled "
        "every this many ns from its emission to the sensor's maximum range's time of flight: "
        "0.25 (the waveform's own bins) to 4, a multiple of 0.25; 0: not stored; a profile "
        "with a receiver only (sensor). The VLP-16's digitiser rate is not published.",
        Range(0, MAX_WAVEFORM_BIN_NS, "ns", note="(0: not stored)"),
    )
    return_mode: str = setting(
        "strongest",
        "Which returns a pulse reports (VLP-16 manual sec. 9.3.2): strongest, last, or dual "
        "(the last and the strongest, or the second strongest where the strongest is the "
        "last); the network's delay is the first reported return; a profile with a receiver "
        "only (sensor).",
        Choice(RETURN_MODES),
    )
    # stored only when not 0 / False, so that datasets and sweeps without motion keep their
    # bytes (as variation above)
    ego_speed_mps: float = setting(
        0.0,
        "The ego vehicle's speed along the road in m/s: the sensor moves while it turns, and "
        "every pulse is cast from where the sensor is at its emission time (sweeps, and "
        "windows under scan timing; docs/sweeps.md, 'Motion').",
        Range(0, MAX_SPEED_MPS, "m/s", note="(0: standing)"),
    )
    ego_yaw_rate_deg_s: float = setting(
        0.0,
        "The ego vehicle's yaw rate in deg/s, counter-clockwise (a left turn) positive: its "
        "heading and its travel turn together (sweeps, and windows under scan timing).",
        Range(-MAX_YAW_RATE_DEG_S, MAX_YAW_RATE_DEG_S, "deg/s", note="(0: straight)"),
    )
    # stored as its size and digest (the poses themselves: the sweep's `ego_trajectory`)
    ego_trajectory: Trajectory | None = setting(
        None,
        "The ego's poses from a trajectory file (simlidar.motion.trajectory: rows t x y z roll "
        "pitch yaw from each sequence's start), interpolated per pulse: linear in position, "
        "slerp in rotation; instead of ego_speed_mps and ego_yaw_rate_deg_s (sweeps only).",
        compare=False,
    )
    moving_objects: bool = setting(
        False,
        "Move each scene's object as the scene catalog's motion.toml says (speed, heading of "
        "travel, yaw rate, drawn once a scene after the static scene's draws; sweeps, and "
        "windows under scan timing).",
        Choice((False, True)),
    )

    def __post_init__(self) -> None:
        if not isinstance(self.ego_trajectory, Trajectory | None):
            raise ConfigError(
                f"ego_trajectory={shown(self.ego_trajectory)}: expected a trajectory "
                "(simlidar.motion.trajectory.load_trajectory) or None"
            )
        if self.ego_trajectory is not None and (self.ego_speed_mps or self.ego_yaw_rate_deg_s):
            raise ConfigError(
                f"ego_speed_mps={self.ego_speed_mps!r}, ego_yaw_rate_deg_s="
                f"{self.ego_yaw_rate_deg_s!r} with a trajectory: expected one way of moving "
                "the ego (--trajectory, or --ego-speed and --ego-yaw-rate)"
            )
        check_window(self, "sample")
        if self.profile is not None and not isinstance(self.profile, Profile):
            raise ConfigError(f"profile={self.profile!r}: expected a Profile or None")
        if math.isfinite(self.fog_visibility_m) and self.receiver is None:
            raise ConfigError(
                f"fog_visibility_m={self.fog_visibility_m!r} (--fog): expected a profile with a "
                f"receiver (--profile sensor), not {self.profile_name!r}: without one every hit "
                "returns, and fog would change nothing"
            )
        if self.rain_rate_mm_h > 0.0 and self.receiver is None:
            raise ConfigError(
                f"rain_rate_mm_h={self.rain_rate_mm_h!r} (--rain): expected a profile with a "
                f"receiver (--profile sensor), not {self.profile_name!r}: without one every hit "
                "returns, and rain would change nothing"
            )
        if self.waveform_bin_ns and (self.waveform_bin_ns / BIN_NS) % 1.0:
            raise ConfigError(
                f"waveform_bin_ns={self.waveform_bin_ns!r} (--waveform-bin): expected a "
                f"multiple of {BIN_NS} ns (the waveform's own bins), or 0"
            )
        sample_bytes = self.sensor.beams * self.width * self.waveform_bins * 4
        if sample_bytes > MAX_CHUNK_BYTES:  # one sample a chunk: a reader would refuse it
            raise ConfigError(
                f"waveform_bin_ns={self.waveform_bin_ns!r} (--waveform-bin): a sample's "
                f"waveforms take {sample_bytes} bytes ({self.sensor.beams} x {self.width} x "
                f"{self.waveform_bins} float32), over the {MAX_CHUNK_BYTES} a chunk may hold; "
                "expected a coarser bin or fewer columns"
            )
        if self.full_waveform and self.receiver is None:
            raise ConfigError(
                f"beam_samples={self.beam_samples!r}, return_mode={self.return_mode!r}, "
                f"waveform_bin_ns={self.waveform_bin_ns!r} (--beam-samples, --return-mode, "
                "--waveform-bin): expected a profile with a receiver "
                f"(--profile sensor), not {self.profile_name!r}: without one a pulse has no "
                "waveform to take returns from"
            )

    @classmethod
    def from_profile(
        cls,
        profile: Profile,
        variation: float | None = None,
        shift_max: float | None = None,
        **fields,
    ) -> "GeneratorConfig":
        """A config that follows ``profile``; ``variation`` and ``shift_max`` given here
        override the profile's. The shipped ``physical`` profile is stored as None (the 1.0.0
        rule), so that its datasets keep the bytes of 1.0.0."""
        physical = (
            profile.name == "physical"
            and profile.pulse_rule == PHYSICAL_RULE
            and profile.receiver is None
        )
        return cls(
            variation=profile.variation if variation is None else variation,
            shift_max=profile.shift if shift_max is None else shift_max,
            profile=None if physical else profile,
            **fields,
        )

    @property
    def profile_name(self) -> str:
        return "physical" if self.profile is None else self.profile.name

    @property
    def moves(self) -> bool:
        """Whether anything moves: the ego vehicle or the scenes' objects."""
        ego = self.ego_speed_mps or self.ego_yaw_rate_deg_s or self.ego_trajectory is not None
        return bool(ego or self.moving_objects)

    @property
    def ego_motion(self) -> "PlanarMotion | Trajectory":
        """The ego's motion from a sequence's start: its trajectory, or its speed and yaw rate
        (standing, where neither is given); ``.poses(t_s)`` of either gives its poses."""
        if self.ego_trajectory is not None:
            return self.ego_trajectory
        return PlanarMotion(self.ego_speed_mps, self.ego_yaw_rate_deg_s)

    @property
    def receiver(self) -> str | None:
        """The profile's receiver (name or file), None where every hit in range returns."""
        return None if self.profile is None else self.profile.receiver

    @property
    def pulse_rule(self) -> dict:
        """missing_delay, noise_on, spikes (simlidar.generator.profiles.Profile)."""
        return dict(PHYSICAL_RULE) if self.profile is None else self.profile.pulse_rule

    @property
    def overrides(self) -> dict:
        """Scene values that differ from the profile's own (they are named in the dataset's
        name): {"variation": ..., "shift_max": ...}."""
        own = (1.0, 0.0) if self.profile is None else (self.profile.variation, self.profile.shift)
        used = {"variation": self.variation, "shift_max": self.shift_max}
        return {k: v for (k, v), mine in zip(used.items(), own) if v != mine}

    @property
    def scan_window_ns(self) -> float | None:
        """The delay unit of scan-timed pulses (:func:`simlidar.sensor.rays.scan_window_ns`);
        None for flash timing."""
        if self.timing != "scan":
            return None
        return scan_window_ns(self.sensor, self.width, self.fov_deg)

    @property
    def extinction_per_m(self) -> float:
        """The atmosphere's extinction coefficient alpha (1/m) at the receiver's wavelength:
        the fog's and the rain's, from Mie theory over their drops
        (:mod:`simlidar.sensor.scattering`; a fog's drops as many as make its extinction in
        visible light Koschmieder's ln(20) / V); 0 in clear air."""
        from simlidar.sensor.scattering import fog_coefficients, rain_coefficients

        fog_on = math.isfinite(self.fog_visibility_m)
        if not fog_on and self.rain_rate_mm_h == 0.0:
            return 0.0
        from simlidar.sensor.receiver import load_receiver

        wavelength = load_receiver(self.receiver).wavelength_nm
        fog = 0.0
        if fog_on:
            fog = fog_coefficients(self.fog_visibility_m, wavelength).extinction_per_m
        if self.rain_rate_mm_h == 0.0:
            return fog
        return fog + rain_coefficients(self.rain_rate_mm_h, wavelength).extinction_per_m

    @property
    def full_waveform(self) -> bool:
        """Whether returns come from each pulse's waveform (a footprint of several sub-rays, a
        return mode other than strongest, or weather, whose echoes join a waveform:
        :func:`simlidar.generator.returns.receive_beams`) rather than from the single ray's
        hit."""
        return (
            self.beam_samples != 1
            or self.return_mode != "strongest"
            or math.isfinite(self.fog_visibility_m)
            or self.rain_rate_mm_h > 0.0
            or self.waveform_bin_ns > 0.0
        )

    @property
    def receiver_tag(self) -> str:
        """What a dataset's or sweep's name says of the receiver's options:
        ``[-fog<V>][-rain<R>][-beam<Q>][-<mode>][-wave<ns>]``, numbers as Python's repr."""
        tag = ""
        if math.isfinite(self.fog_visibility_m):
            tag += f"-fog{float(self.fog_visibility_m)!r}"
        if self.rain_rate_mm_h:
            tag += f"-rain{float(self.rain_rate_mm_h)!r}"
        tag += f"-beam{self.beam_samples}" if self.beam_samples != 1 else ""
        tag += f"-{self.return_mode}" if self.return_mode != "strongest" else ""
        tag += f"-wave{float(self.waveform_bin_ns)!r}" if self.waveform_bin_ns else ""
        return tag

    @property
    def motion_tag(self) -> str:
        """What a dataset's or sweep's name says of its motion:
        ``[-ego<v>][-traj<sha256, 8 digits>][-yaw<w>][-moving]``, numbers as Python's repr."""
        tag = f"-ego{float(self.ego_speed_mps)!r}" if self.ego_speed_mps else ""
        if self.ego_trajectory is not None:
            tag += f"-traj{self.ego_trajectory.summary()['sha256'][:8]}"
        tag += f"-yaw{float(self.ego_yaw_rate_deg_s)!r}" if self.ego_yaw_rate_deg_s else ""
        return tag + ("-moving" if self.moving_objects else "")

    @property
    def waveform_bins(self) -> int:
        """Samples of each stored waveform (0: none stored): t = k waveform_bin_ns up to the
        sensor's maximum range's time of flight."""
        if not self.waveform_bin_ns:
            return 0
        return int(self.sensor.tof_max_ns // self.waveform_bin_ns) + 1

    @property
    def reported_returns(self) -> int:
        """Returns a pulse reports in the ``returns_*`` datasets (2 in dual mode, else 1), 0
        where they are not stored (:func:`simlidar.dataset.schema.reported_returns`)."""
        if not (self.receiver is not None and self.full_waveform):
            return 0
        return 2 if self.return_mode == "dual" else 1

    @property
    def split_sizes(self) -> dict[str, int]:
        return {"train": self.train_size, "test": self.test_size}

    def with_noise(self, noise: float) -> "GeneratorConfig":
        return replace(self, noise=noise)

    def to_dict(self) -> dict:
        values = asdict(self)
        values["sensor"] = self.sensor.to_dict()
        if values["variation"] == 1.0:
            del values["variation"]  # absent means 1 (and keeps older datasets' bytes)
        if values["profile"] is None:
            del values["profile"]  # absent means the physical rule of 1.0.0 (same reason)
        else:
            values["profile"] = self.profile.to_dict()  # optional keys only where set
        if values["timing"] == "flash":
            del values["timing"]  # absent means flash (same reason)
        if values["fog_visibility_m"] == math.inf:
            del values["fog_visibility_m"]  # absent means clear air (same reason)
        if values["rain_rate_mm_h"] == 0.0:
            del values["rain_rate_mm_h"]  # absent means no rain (same reason)
        if values["beam_samples"] == 1:
            del values["beam_samples"]  # absent means one ray a pulse (same reason)
        if values["waveform_bin_ns"] == 0.0:
            del values["waveform_bin_ns"]  # absent means no waveform stored (same reason)
        if values["return_mode"] == "strongest":
            del values["return_mode"]  # absent means the strongest return (same reason)
        for key in ("ego_speed_mps", "ego_yaw_rate_deg_s", "moving_objects"):
            if not values[key]:
                del values[key]  # absent means no motion (same reason)
        if self.ego_trajectory is None:
            del values["ego_trajectory"]  # same reason
        else:  # the poses are the sweep's dataset `ego_trajectory`
            values["ego_trajectory"] = self.ego_trajectory.summary()
        return values

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), sort_keys=True)

    @classmethod
    def from_dict(cls, values: dict) -> "GeneratorConfig":
        """The inverse of :meth:`to_dict`, every key checked: a ConfigError naming the key for
        anything else (a damaged or hostile dataset attribute)."""
        known = [f.name for f in fields(cls)]
        if not isinstance(values, dict):
            raise ConfigError(f"configuration {shown(values)}: expected an object of {known}")
        for key in values:
            if key not in known:
                raise key_error("configuration", key, f"one of {known}", key)
        values = dict(values)
        values["sensor"] = (
            Sensor.from_dict(values["sensor"]) if "sensor" in values else default_sensor()
        )
        profile = values.get("profile")
        if profile is not None:
            name = profile.get("name") if isinstance(profile, dict) else None
            if not isinstance(name, str):
                raise key_error(
                    "configuration", "profile", "a profile's keys with its name", profile
                )
            given = {k: v for k, v in profile.items() if k != "name"}
            values["profile"] = checked_profile(f"configuration: profile {name!r}", name, given)
        return cls(**values)
