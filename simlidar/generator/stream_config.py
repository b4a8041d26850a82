"""A stream dataset's configuration (``simlidar stream``): one frozen dataclass, stored as JSON in
every split file (attribute ``config``)."""

import json
from dataclasses import asdict, dataclass

from simlidar.errors import ConfigError
from simlidar.generator.config import SIZE, check_window
from simlidar.sensor.model import Sensor, default_sensor
from simlidar.settings import Range, setting

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

    def __post_init__(self) -> None:
        check_window(self, "stream")
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

    def to_json(self) -> str:
        """The configuration as stored (attribute ``config``): every field, the sensor by its
        name (its model is the attribute ``sensor``), so that the card's "Regenerate" passes
        them to :func:`simlidar.generator.stream_files.generate_streams` as they are."""
        values = asdict(self) | {"sensor": self.sensor.name}
        return json.dumps(values, sort_keys=True)
