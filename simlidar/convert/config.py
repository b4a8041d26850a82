"""The converters' options: one frozen dataclass per source, holding every default, accepted
range and help text (:mod:`simlidar.settings`). The library functions (``convert_kitti``,
``convert_dvs_barrel``) and the command line (``simlidar convert``) take their defaults from
here; a converted split stores its options as JSON."""

import json
from dataclasses import asdict, dataclass

from simlidar.dataset.dvs_barrel import CLASSES as DVS_CLASSES
from simlidar.errors import ConfigError
from simlidar.settings import Choice, Range, check, check_value, setting

SEED = Range(0, 2**63, "an integer", high_open=True)
FRACTION = Range(0, 1, "a fraction", low_open=True, high_open=True)

# Accepted option values (docs/converters.md): cells from 0.01 degree (far finer than any
# HDL-64E step; 36,000 columns) to 10 degrees, and a delay-1 range from 1 m to 1 km (8 times the
# HDL-64E's 120 m). Outside these the front view means nothing: 1e-300 degree cells overflow
# the cell indices, a 1e-300 m range turns every return into "no return" (1.0).
RES_DEG = Range(0.01, 10, "degrees")
MAX_RANGE_M = Range(1, 1000, "metres")


@dataclass(frozen=True)
class KittiConfig:
    """Everything that decides a converted KITTI dataset's bytes (with the input and version)."""

    crop: tuple[int, int] = setting(
        (50, 118), "Crop size: rows columns (front-view cells; the paper's 50 x 118)."
    )
    res_h_deg: float = setting(
        0.18,
        "Horizontal front-view resolution, degrees (the HDL-64E's azimuth step at 10 Hz).",
        RES_DEG,
    )
    res_v_deg: float = setting(
        0.4, "Vertical front-view resolution, degrees (the HDL-64E's ~0.4 deg spacing).", RES_DEG
    )
    max_range_m: float = setting(
        100.0, "Range (m) whose time of flight is delay 1 (the VLP-16's maximum).", MAX_RANGE_M
    )
    test_fraction: float = setting(
        0.2,
        "Fraction of the frames with objects in the test split (the paper: 8,000 of 40,456 crops).",
        FRACTION,
    )
    seed: int = setting(0, "Seed of the train/test split of the frames.", SEED)

    def __post_init__(self) -> None:
        crop = self.crop
        if not (
            isinstance(crop, tuple | list)
            and len(crop) == 2
            and all(isinstance(c, int) and 1 <= c <= 4096 for c in crop)
        ):
            raise ConfigError(f"crop={crop!r}: expected (rows, columns), integers in [1, 4096]")
        object.__setattr__(self, "crop", tuple(crop))
        check_value(KittiConfig, "res_v_deg", self.res_v_deg, _say(self.res_v_deg))
        low, high = RES_DEG.low, RES_DEG.high
        columns = 360.0 / self.res_h_deg if RES_DEG.accepts(self.res_h_deg) else 0.5
        if abs(columns - round(columns)) > 1e-9 * columns:
            raise ConfigError(
                f"res_h_deg={self.res_h_deg!r}: expected degrees in (0, {high:g}] dividing 360 "
                f"into at most {round(360 / low)} columns (0.01, ..., 0.08, 0.09, 0.1, 0.12, "
                "0.15, 0.16, 0.18, 0.2, ...), so that the front view closes"
            )
        if self.crop[1] > self.columns:
            raise ConfigError(f"crop={self.crop}: wider than the {self.columns} columns of 360 deg")
        check(self)

    @property
    def columns(self) -> int:
        """Columns of the full 360 degree front view."""
        return round(360.0 / self.res_h_deg)

    def to_json(self) -> str:
        return json.dumps(asdict(self), sort_keys=True)


@dataclass(frozen=True)
class DvsConfig:
    """Everything that decides a converted DVS barrel dataset's bytes (with the input)."""

    window_us: float | None = setting(
        None, "Time window (us) whose end is delay 1 (default: longest recording + 1)."
    )
    address_base: int = setting(
        1, "Whether x and y addresses count from 0 or from 1 (MATLAB).", Choice((0, 1))
    )
    labels: tuple[str, ...] | None = setting(
        None,
        "One class character (0-9, A-Z) per recording, e.g. 0123...; default: the ROI struct's "
        "'label' field.",
    )
    # the split's settings as KittiConfig's (alike in form): other defaults, other help
    test_fraction: float = setting(
        0.5,
        "Fraction of each class's recordings in test (at least one stays in train).",
        FRACTION,
    )
    seed: int = setting(0, "Seed of the train/test split (one stream per class).", SEED)

    def __post_init__(self) -> None:
        if self.window_us is not None and not (
            isinstance(self.window_us, float | int) and 0 < self.window_us < 1e15
        ):
            raise ConfigError(f"window_us={self.window_us!r}: expected positive microseconds")
        if isinstance(self.address_base, bool):
            raise ConfigError(f"address_base={self.address_base!r}: expected 0 or 1")
        if self.labels is not None:
            labels = tuple(str(c).upper() for c in self.labels)
            unknown = [c for c in labels if c not in DVS_CLASSES]
            if unknown:
                raise ConfigError(f"labels: {unknown[0]!r}, expected characters 0-9 or A-Z")
            object.__setattr__(self, "labels", labels)
        check(self)

    def to_json(self) -> str:
        return json.dumps(asdict(self), sort_keys=True)


def _say(value):
    return lambda name, expected: f"{name}={value!r}: expected {expected}"
