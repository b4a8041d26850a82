"""The generator's configuration: one frozen dataclass, stored as JSON in every split file."""

import json
import math
from dataclasses import asdict, dataclass, field, replace

from simlidar.errors import ConfigError
from simlidar.profiles import PHYSICAL_RULE, Profile
from simlidar.sensor.vlp16 import VLP16

MAX_SPLIT_SIZE = 10**9  # samples per split


@dataclass(frozen=True)
class GeneratorConfig:
    """Everything that decides a dataset's bytes (with the scene catalog and the version)."""

    classes: int = 32  # 32: layout x object; 8: layout alone; 4: object alone (per catalog)
    noise: float = 0.2  # a in U(0, a), added to every normalised delay
    train_size: int = 3000  # samples in train.h5 (the paper's size)
    test_size: int = 600  # samples in test.h5
    seed: int = 0  # root of every random stream (numpy SeedSequence)
    width: int = 16  # azimuth columns W of a sample
    fov_deg: float = 36.0  # horizontal field of view of the W columns, centred ahead
    min_object_hits: int = 4  # k: a labelled object is hit by at least k pulses
    max_attempts: int = 200  # redraws allowed per sample before giving up
    shift_max: float = 0.0  # delay-shift augmentation: each sample's returns move U(-s, s)
    # scene variation: every parameter range of the catalog shrunk around its centre by this
    # factor (1: the recipes as written); stored only when not 1, so the files of datasets
    # made before the option existed stay byte for byte the same
    variation: float = 1.0
    sensor: VLP16 = field(default_factory=VLP16)
    # the dataset profile (simlidar.profiles) whose pulse rule the pixels follow; None: the
    # physical rule of dataset version 1.0.0 (stored only when not None, for the same reason
    # as variation). `variation` and `shift_max` above are the values used, which start from
    # the profile's and may be overridden (docs/profiles.md)
    profile: Profile | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.classes, int) or self.classes < 2:
            raise ConfigError(f"classes={self.classes!r}: expected an integer >= 2")
        if not (isinstance(self.noise, float | int) and 0.0 <= self.noise <= 1.0):
            raise ConfigError(f"noise={self.noise!r}: expected a level in [0, 1]")
        for name in ("train_size", "test_size"):
            value = getattr(self, name)
            if not isinstance(value, int) or not self.classes <= value <= MAX_SPLIT_SIZE:
                raise ConfigError(
                    f"{name}={value!r}: expected an integer in [{self.classes}, "
                    f"{MAX_SPLIT_SIZE}] (at least one sample of every class: classes are "
                    "balanced)"
                )
        if not isinstance(self.seed, int) or not 0 <= self.seed < 2**63:
            raise ConfigError(f"seed={self.seed!r}: expected an integer in [0, 2**63)")
        if not isinstance(self.width, int) or not 1 <= self.width <= 1024:
            raise ConfigError(f"width={self.width!r}: expected an integer in [1, 1024]")
        if not (math.isfinite(self.fov_deg) and 0.0 < self.fov_deg < 180.0):
            raise ConfigError(f"fov_deg={self.fov_deg!r}: expected degrees in (0, 180)")
        if not isinstance(self.min_object_hits, int) or self.min_object_hits < 1:
            raise ConfigError(f"min_object_hits={self.min_object_hits!r}: expected >= 1")
        if not isinstance(self.max_attempts, int) or self.max_attempts < 1:
            raise ConfigError(f"max_attempts={self.max_attempts!r}: expected >= 1")
        if not (
            isinstance(self.variation, float | int)
            and not isinstance(self.variation, bool)
            and 0.0 < self.variation <= 1.0
        ):
            raise ConfigError(
                f"variation={self.variation!r}: expected a factor in (0, 1] "
                "(1: the scene catalog's ranges as written)"
            )
        if self.profile is not None and not isinstance(self.profile, Profile):
            raise ConfigError(f"profile={self.profile!r}: expected a Profile or None")
        if not 0.0 <= self.shift_max < 1.0:
            raise ConfigError(f"shift_max={self.shift_max!r}: expected a value in [0, 1)")

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
        physical = profile.name == "physical" and profile.pulse_rule == PHYSICAL_RULE
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
    def pulse_rule(self) -> dict:
        """missing_delay, noise_on, spikes (simlidar.profiles.Profile)."""
        return dict(PHYSICAL_RULE) if self.profile is None else self.profile.pulse_rule

    @property
    def overrides(self) -> dict:
        """Scene values that differ from the profile's own (they are named in the dataset's
        name): {"variation": ..., "shift_max": ...}."""
        own = (1.0, 0.0) if self.profile is None else (self.profile.variation, self.profile.shift)
        used = {"variation": self.variation, "shift_max": self.shift_max}
        return {k: v for (k, v), mine in zip(used.items(), own) if v != mine}

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
        return values

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), sort_keys=True)

    @classmethod
    def from_dict(cls, values: dict) -> "GeneratorConfig":
        values = dict(values)
        values["sensor"] = VLP16.from_dict(values.get("sensor", {}))
        if values.get("profile") is not None:
            values["profile"] = Profile(**values["profile"])
        return cls(**values)
