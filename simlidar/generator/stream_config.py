"""A stream dataset's configuration (``simlidar stream``): one frozen dataclass, stored as JSON in
every split file (attribute ``config``)."""

import json
import math
from dataclasses import asdict, dataclass

from simlidar.errors import ConfigError
from simlidar.generator.config import SIZE, GeneratorConfig, check_window
from simlidar.sensor.model import Sensor, default_sensor
from simlidar.settings import Range, help_of, rule_of, setting

# the longest span a stream may have: every ray stays in the ray caster's cell (an object at
# 108 m closing at 28 m/s for 2 s with the ego's 24 m) and a sample's events in one chunk
MAX_SPAN_S = 2.0


@dataclass(frozen=True)
class StreamConfig:
    """Everything that decides a stream dataset's bytes (with the scene catalog, its scenarios
    and the version)."""

    classes: int = setting(
        4,
        "4: object alone (the default: what comes into view), 32: layout x object, 8: layout.",
        Range(2, None, "an integer"),
    )
    train_size: int = setting(3000, "Streams in train.h5.", SIZE)
    test_size: int = setting(600, "Streams in test.h5.", SIZE)
    seed: int = setting(
        0,
        "Root of every random stream (numpy SeedSequence).",
        Range(0, 2**63, "an integer", high_open=True),
    )
    width: int = setting(
        32,
        "Azimuth columns of the window, each its own firing cycle.",
        Range(1, 1024, "an integer"),
    )
    fov_deg: float = setting(
        36.0,
        "Horizontal field of view of the window, centred ahead, degrees.",
        Range(0, 180, "degrees", low_open=True, high_open=True),
    )
    rotations: int = setting(
        10,
        "Rotations of the sensor a stream spans (10 at a VLP-16's 600 RPM: 1 s).",
        Range(2, 1000, "an integer"),
    )
    min_object_hits: int = setting(
        4, "A stream's object returns at least this many events.", Range(1, None, "an integer")
    )
    max_attempts: int = setting(
        200, "Scenario redraws allowed per stream before giving up.", Range(1, None, "an integer")
    )
    variation: float = setting(
        1.0,
        "Scene variation: every parameter range of the scene catalog's layout and object "
        "recipes shrunk around its centre by this factor (1: the recipes as written; the "
        "scenarios and the ego's speed keep theirs).",
        Range(0, 1, "a factor", low_open=True),
    )
    sensor: Sensor = setting(
        help="The sensor model (a file of sensors/, simlidar.sensor.load_sensor).",
        default_factory=default_sensor,
    )
    # the receiver and its weather (issue 60, after the calibrated receiver of issue 62); each
    # stored only when set, so that streams without a receiver keep version 1.0.0's bytes
    profile: str | None = setting(
        None,
        "A profile with a receiver (sensor, or a .toml file): a hit is an event only when the "
        "receiver detects it, with its range noise, reflectivity byte and false alarms "
        "(docs/streams.md); None: every hit in range is an event.",
    )
    fog_visibility_m: float = setting(
        math.inf,
        help_of(GeneratorConfig, "fog_visibility_m"),
        rule_of(GeneratorConfig, "fog_visibility_m"),
    )
    rain_rate_mm_h: float = setting(
        0.0, help_of(GeneratorConfig, "rain_rate_mm_h"), rule_of(GeneratorConfig, "rain_rate_mm_h")
    )

    def __post_init__(self) -> None:
        check_window(self, "stream")
        if self.profile is not None and not isinstance(self.profile, str):
            raise ConfigError(
                f"profile={self.profile!r}: expected a profile's name or file (sensor), or None"
            )
        self.receiver_config  # noqa: B018 (checks the profile, fog and rain, as generate does)
        if self.span_s > MAX_SPAN_S:
            raise ConfigError(
                f"rotations={self.rotations}: {self.span_s:g} s at {self.sensor.rpm:g} RPM; "
                f"expected a span of at most {MAX_SPAN_S:g} s"
            )

    @property
    def rotation_us(self) -> float:
        """One rotation of the head, microseconds (100,000 at 600 RPM)."""
        return 60e6 / self.sensor.rpm

    @property
    def span_s(self) -> float:
        """The time a stream spans, s: its rotations."""
        return self.rotations * self.rotation_us * 1e-6

    @property
    def split_sizes(self) -> dict[str, int]:
        return {"train": self.train_size, "test": self.test_size}

    @property
    def receiver_config(self) -> GeneratorConfig | None:
        """The receiver's configuration (:func:`simlidar.generator.returns.receive_hits` reads
        its profile, sensor, seed and weather) where the streams have a receiver, else None; a
        ConfigError for a profile that cannot be read or has no receiver, and for weather
        without one."""
        from simlidar.generator.profiles import load_profile

        if self.profile is None:
            weather = GeneratorConfig(
                sensor=self.sensor, width=self.width, fov_deg=self.fov_deg,
                fog_visibility_m=self.fog_visibility_m, rain_rate_mm_h=self.rain_rate_mm_h,
            )  # fmt: skip
            return weather if weather.receiver is not None else None  # refused weather above
        chosen = load_profile(self.profile)
        if chosen.receiver is None:
            raise ConfigError(
                f"profile={self.profile!r} (--profile): expected a profile with a receiver "
                "(sensor): a stream's events follow no other profile's rule"
            )
        return GeneratorConfig.from_profile(
            chosen, classes=self.classes, seed=self.seed, sensor=self.sensor, width=self.width,
            fov_deg=self.fov_deg, fog_visibility_m=self.fog_visibility_m,
            rain_rate_mm_h=self.rain_rate_mm_h,
        )  # fmt: skip

    @property
    def version(self) -> str:
        """The dataset version these streams are written as: 1.1.0 through a receiver (the
        stream source's current), else 1.0.0, whose records streams without one keep."""
        from simlidar.dataset.stream import SOURCE, UNRECEIVED_VERSION

        return SOURCE.version if self.profile is not None else UNRECEIVED_VERSION

    def to_json(self) -> str:
        """The configuration as stored (attribute ``config``): every field, the sensor by its
        name (its model is the attribute ``sensor``), so that the card's "Regenerate" passes
        them to :func:`simlidar.generator.stream_files.generate_streams` as they are; the
        receiver's fields only where set (absent: none, clear air)."""
        values = asdict(self) | {"sensor": self.sensor.name}
        for name, unset in (("profile", None), ("fog_visibility_m", math.inf),
                            ("rain_rate_mm_h", 0.0)):  # fmt: skip
            if values[name] == unset:
                del values[name]
        return json.dumps(values, sort_keys=True)
