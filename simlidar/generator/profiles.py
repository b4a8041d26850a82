"""Dataset profiles: what a sample looks like beyond the scene catalog.

A profile is a small TOML file in ``profiles/`` (shipped in the wheel) or anywhere on disk. It
names the scene variation, the delay-shift augmentation, the delay written for a missing
return, which pixels receive the uniform noise, and which pixels a spiking network reads as
input spikes; optionally, the receiver whose physics decides which hits return (issue 41).
``docs/profiles.md`` explains each value and the shipped profiles:

* ``paper`` (the default of ``simlidar generate``): the protocol that reproduces the paper's
  accuracy-versus-noise table;
* ``physical``: the pulses of dataset version 1.0.0, byte for byte;
* ``sensor``: the physical rule with a receiver (``sensors/receivers/vlp16.toml``) and the
  materials of ``scenes/materials.toml``: a return is what the receiver detects
  (:mod:`simlidar.generator.returns`).

Delays always stay in [0, 1] (the split schema's contract): noise is clipped at 1.0, the end of
the listening window.
"""

from dataclasses import asdict, dataclass
from pathlib import Path

from simlidar.content import (
    content_dir,
    finite_number,
    key_error,
    read_named_toml,
    shipped_or_path,
)
from simlidar.errors import ConfigError, shown

DEFAULT_PROFILE = "paper"
MAX_PROFILE_BYTES = 64 * 1024  # a profile is a few lines; anything larger is not one
WHERE = ("all", "returns")  # noise_on / spikes: every pixel, or only the pixels with a return
MISSING = (0.0, 1.0)  # the start or the end of the listening window
KEYS = {"description", "variation", "shift", "missing_delay", "noise_on", "spikes"}
# Optional keys; absent, a profile's pulses are those it had before the key existed (and a
# stored profile without them keeps its bytes)
OPTIONAL_KEYS = {"receiver", "materials"}


@dataclass(frozen=True)
class Profile:
    """One dataset profile (fields as in the TOML file; ``name`` is the file's stem)."""

    name: str
    description: str
    variation: float  # scene parameter ranges shrunk around their centre by this factor
    shift: float  # delay-shift augmentation: every return of a sample moves by U(-s, s)
    missing_delay: float  # the delay written where no return came back: 0.0 or 1.0
    noise_on: str  # "all": U(0, a) on every pixel; "returns": on returns only
    spikes: str  # "all": every pixel is an input spike; "returns": only delays < 1.0
    # a receiver of sensors/receivers/ by name, or a receiver file: which hits return, with
    # what intensity (simlidar.generator.returns); None: every hit in range returns
    receiver: str | None = None
    # the materials file surfaces are made of (with `receiver` only); None: scenes/materials.toml
    materials: str | None = None

    @property
    def pulse_rule(self) -> dict:
        """The three values that decide the pixels (beyond the scenes and the noise level)."""
        return {
            "missing_delay": self.missing_delay,
            "noise_on": self.noise_on,
            "spikes": self.spikes,
        }

    def to_dict(self) -> dict:
        """The profile's keys and name; an optional key only where it is set (so the stored
        configuration of a profile without it keeps its bytes)."""
        values = asdict(self)
        return {k: v for k, v in values.items() if k not in OPTIONAL_KEYS or v is not None}


PHYSICAL_RULE = {"missing_delay": 1.0, "noise_on": "returns", "spikes": "returns"}


def profile_names() -> list[str]:
    """The shipped profiles' names."""
    return sorted(p.stem for p in content_dir("profiles").glob("*.toml"))


def load_profile(name_or_path: str | Path) -> Profile:
    """A shipped profile by name, or a profile file by path; every key checked.

    Raises ConfigError naming the file, the key and what was expected.
    """
    path = shipped_or_path(name_or_path, "profiles", "profile")
    where = f"profile {path}"
    profile = checked_profile(where, path.stem, read_named_toml(path, where, MAX_PROFILE_BYTES))
    if profile.receiver is not None:  # the files it names, read now: a bad one fails here
        from simlidar.generator.returns import receiver_physics

        try:
            receiver_physics(profile)
        except ConfigError as exc:
            raise ConfigError(f"{where}: {exc}") from None
    return profile


def checked_profile(where: str, name: str, data: dict) -> Profile:
    """The profile ``name`` of a profile file's keys ``data``, every key checked (also a
    profile stored in a dataset's configuration); a ConfigError starting with ``where``."""
    if not isinstance(data, dict):
        raise ConfigError(f"{where}: expected a table of {sorted(KEYS)}, got {shown(data)}")
    for key in data:
        if key not in KEYS | OPTIONAL_KEYS:
            raise key_error(where, key, f"one of {sorted(KEYS | OPTIONAL_KEYS)}", key)
    for key in sorted(KEYS - set(data)):
        raise ConfigError(f"{where}: key '{key}' is missing")
    if not isinstance(data["description"], str):
        raise key_error(where, "description", "a string", data["description"])
    if not (finite_number(data["variation"]) and 0.0 < data["variation"] <= 1.0):
        raise key_error(where, "variation", "a factor in (0, 1]", data["variation"])
    if not (finite_number(data["shift"]) and 0.0 <= data["shift"] < 1.0):
        raise key_error(where, "shift", "a value in [0, 1)", data["shift"])
    if not (finite_number(data["missing_delay"]) and data["missing_delay"] in MISSING):
        raise key_error(
            where,
            "missing_delay",
            "0.0 (start of the window) or 1.0 (its end)",
            data["missing_delay"],
        )
    for key in ("noise_on", "spikes"):
        if data[key] not in WHERE:
            raise key_error(where, key, f"one of {list(WHERE)}", data[key])
    if data["spikes"] == "returns" and data["missing_delay"] != 1.0:
        raise key_error(
            where,
            "spikes",
            "'all' when missing_delay is 0.0 ('returns' reads pixels "
            "below 1.0 as spikes, so a missing return at 0.0 would fire first)",
            data["spikes"],
        )
    for key in OPTIONAL_KEYS & set(data):
        if not isinstance(data[key], str) or not data[key].strip():
            what = "a receiver name or a .toml file" if key == "receiver" else "a .toml file"
            raise key_error(where, key, what, data[key])
    if "materials" in data and "receiver" not in data:
        what = "no materials without a receiver (key 'receiver')"
        raise key_error(where, "materials", what, data["materials"])
    return Profile(
        name=name,
        description=data["description"],
        variation=float(data["variation"]),
        shift=float(data["shift"]),
        missing_delay=float(data["missing_delay"]),
        noise_on=data["noise_on"],
        spikes=data["spikes"],
        receiver=data.get("receiver"),
        materials=data.get("materials"),
    )
