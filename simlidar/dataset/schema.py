"""The split files' schemas: what every generated or converted split holds; and a sweep's
frames file (``simlidar sweep``) and the point clouds made from it.

Every dataset and attribute is described in ``docs/dataset-format.md`` (the generator's),
``docs/converters.md`` (converted real data) and ``docs/sweeps.md`` (the frames file); keep
them in step.
"""

import re
from dataclasses import dataclass

import numpy as np

from simlidar.dataset.version import CONVERTED, GENERATOR, SOURCES
from simlidar.errors import DatasetError
from simlidar.sensor.receiver import RETURN_MODES
from simlidar.settings import Choice, Range

CHUNK_SAMPLES = 256
SPLITS = ("train", "test")

# The generator's splits: name -> (dtype, trailing shape given the rows H and the width W);
# H is the sensor's number of beams (16 for the VLP-16)
SCHEMA: dict[str, tuple[str, object]] = {
    "delays": ("float32", lambda h, w: (h, w)),
    "clean_delays": ("float32", lambda h, w: (h, w)),
    "tof_ns": ("float32", lambda h, w: (h, w)),
    "surface": ("uint8", lambda h, w: (h, w)),
    "labels": ("int64", lambda h, w: ()),
    "layout": ("uint8", lambda h, w: ()),
    "object": ("uint8", lambda h, w: ()),
    "object_pose": ("float32", lambda h, w: (3,)),
    "object_hits": ("int32", lambda h, w: ()),
    "attempts": ("int32", lambda h, w: ()),
    "phase": ("float32", lambda h, w: ()),
    "shift": ("float32", lambda h, w: ()),
}
# Stored besides SCHEMA by scan-timed datasets (attribute timing = "scan") only, so that the
# files of flash datasets keep their bytes
SCAN_SCHEMA: dict[str, tuple[str, object]] = {
    "emission_ns": ("float64", lambda h, w: (h, w)),
}
# Stored besides SCHEMA by datasets of a profile with a receiver (attribute `receiver`, profile
# `sensor`) only, for the same reason
RECEIVER_SCHEMA: dict[str, tuple[str, object]] = {
    "intensity": ("uint8", lambda h, w: (h, w)),
    "reflectance": ("float32", lambda h, w: (h, w)),
    "power_w": ("float32", lambda h, w: (h, w)),
}
# Stored besides RECEIVER_SCHEMA by datasets of a beam footprint or a return mode other than
# strongest (attribute `return_mode`) only, for the same reason: name -> (dtype, trailing shape
# given H, W and the returns R a pulse reports, 2 in dual mode, else 1)
RETURNS_SCHEMA: dict[str, tuple[str, object]] = {
    "echoes": ("uint8", lambda h, w, r: (h, w)),
    "returns_tof_ns": ("float32", lambda h, w, r: (h, w, r)),
    "returns_intensity": ("uint8", lambda h, w, r: (h, w, r)),
    "returns_surface": ("uint8", lambda h, w, r: (h, w, r)),
}
# Stored besides RETURNS_SCHEMA by datasets that keep each pulse's waveform (attribute
# `waveform_bins`, T) only: name -> (dtype, trailing shape given H, W and T). Its chunks hold one
# sample each (WAVEFORM_CHUNK), a sample being H x W x T x 4 bytes
WAVEFORM_SCHEMA: dict[str, tuple[str, object]] = {
    "waveform": ("float32", lambda h, w, t: (h, w, t)),
}
WAVEFORM_CHUNK = 1
# Stored besides the others by datasets in motion (``--ego-speed``, ``--ego-yaw-rate``,
# ``--moving-objects`` under scan timing; :func:`in_motion`) only: each sample's object's motion
# as drawn (speed_mps, heading_deg, yaw_rate_deg_s; zeros without object or motion) and the
# ego's (speed_mps, yaw_rate_deg_s)
MOTION_SCHEMA: dict[str, tuple[str, object]] = {
    "object_motion": ("float32", lambda h, w: (3,)),
    "ego_motion": ("float32", lambda h, w: (2,)),
}
# the configuration keys (attribute ``config``) of a dataset in motion, stored only when set
MOTION_CONFIG_KEYS = frozenset({"ego_speed_mps", "ego_yaw_rate_deg_s", "moving_objects"})
# A sweep's frames file: its name, its `format` attribute and its datasets, name -> (dtype,
# trailing shape given the lasers H and the cycles C of a rotation; SCHEMA's form, another
# file's); beside them `emission_ns` (H, C) float64, the same for every frame. Its version:
# simlidar.dataset.version.SWEEP_VERSION
SWEEP_FILE = "frames.h5"
SWEEP_FORMAT = "simlidar-sweep"
SWEEP_SCHEMA: dict[str, tuple[str, object]] = {
    "range_m": ("float32", lambda h, c: (h, c)),
    "surface": ("uint8", lambda h, c: (h, c)),
    "intensity": ("float32", lambda h, c: (h, c)),
    "labels": ("int64", lambda h, c: ()),
    "layout": ("uint8", lambda h, c: ()),
    "object": ("uint8", lambda h, c: ()),
    "object_pose": ("float32", lambda h, c: (3,)),
    "object_box": ("float32", lambda h, c: (7,)),
    "object_points": ("int32", lambda h, c: ()),
    "phase": ("float64", lambda h, c: ()),
}
# Stored besides SWEEP_SCHEMA by sweeps of a beam footprint or a return mode other than
# strongest (attribute `return_mode`) only: name -> (dtype, trailing shape given H, C and the
# returns R a pulse reports, 2 in dual mode, else 1)
SWEEP_RETURNS_SCHEMA: dict[str, tuple[str, object]] = {
    "echoes": ("uint8", lambda h, c, r: (h, c)),
    "returns_range_m": ("float32", lambda h, c, r: (h, c, r)),
    "returns_intensity": ("float32", lambda h, c, r: (h, c, r)),
    "returns_surface": ("uint8", lambda h, c, r: (h, c, r)),
}
# A frame's returns as a point cloud (simlidar.generator.frames.frame_points), every field of
# which the PLY and PCD exports write
POINT_DTYPE = np.dtype(
    [
        ("x", "<f4"),
        ("y", "<f4"),
        ("z", "<f4"),
        ("intensity", "<f4"),
        ("surface", "u1"),
        ("laser", "u1"),
        ("t_ns", "<f8"),
    ]
)
# ... and of a sweep that stores every reported return: each return a point, numbered in order
# of arrival (1: the nearest), with the pulse's count of distinct returns (as LAS numbers them)
RETURN_POINT_DTYPE = np.dtype(
    POINT_DTYPE.descr + [("return_number", "u1"), ("number_of_returns", "u1")]
)
# ... and, in a sweep in motion, the PLY and PCD exports' points also carry their coordinates
# deskewed to the frame's reference pose and their instance id (1: the labelled object)
MOTION_POINT_FIELDS = [
    ("x_deskewed", "<f4"),
    ("y_deskewed", "<f4"),
    ("z_deskewed", "<f4"),
    ("instance", "<u2"),
]


# Stored besides SWEEP_SCHEMA by sweeps in motion (attribute `sequence_frames`: the ego or the
# objects move) only: each frame's sequence, its first firing's time from the sequence's start,
# the sensor's pose in the scene frame at the frame's reference time (its middle cycle, facing
# forward; a 3 x 4 [R | p] as KITTI's poses.txt writes one) and its object's motion as drawn
# (speed_mps, heading_deg, yaw_rate_deg_s; zeros without object)
SWEEP_MOTION_SCHEMA: dict[str, tuple[str, object]] = {
    "sequence": ("int64", lambda h, c: ()),
    "start_ns": ("float64", lambda h, c: ()),
    "ego_pose": ("float64", lambda h, c: (3, 4)),
    "object_motion": ("float32", lambda h, c: (3,)),
}


def sweep_schema(returns: int = 0, motion: bool = False) -> dict[str, tuple[str, object]]:
    """:data:`SWEEP_SCHEMA`, :data:`SWEEP_RETURNS_SCHEMA` where a pulse reports ``returns``
    > 0 returns (their trailing shapes then given H and C alone), and
    :data:`SWEEP_MOTION_SCHEMA` for a sweep in motion."""
    schema = dict(SWEEP_SCHEMA) | (SWEEP_MOTION_SCHEMA if motion else {})
    if not returns:
        return schema
    return schema | {
        name: (dtype, lambda h, c, tail=tail: tail(h, c, returns))
        for name, (dtype, tail) in SWEEP_RETURNS_SCHEMA.items()
    }


# The shuffle filter helps gzip on the noisy delays (random mantissas) and hurts it on the
# quantised clean delays and times of flight (measured: smaller and faster without it).
SHUFFLED = {"delays", "phase", "shift", "object_pose", "reflectance", "power_w", "returns_tof_ns"}
REQUIRED_ATTRS = (
    "dataset_version",
    "simlidar_version",
    "config",
    "seed",
    "noise",
    "split",
    "class_names",
    "class_mode",
    "sensor",
)


@dataclass(frozen=True)
class Text:
    """A string attribute; with ``pattern``, one that matches it (described by ``what``)."""

    pattern: str | None = None
    what: str = "a string"

    def accepts(self, value) -> bool:
        return isinstance(value, str) and (
            self.pattern is None or re.fullmatch(self.pattern, value) is not None
        )

    def expected(self) -> str:
        return self.what


@dataclass(frozen=True)
class JsonObject:
    """A string attribute holding a JSON object (decoded by the reader), with string values
    under ``keys``."""

    keys: tuple[str, ...] = ()

    def accepts(self, value) -> bool:
        return isinstance(value, dict) and all(isinstance(value.get(k), str) for k in self.keys)

    def expected(self) -> str:
        where = f" with strings under {list(self.keys)}" if self.keys else ""
        return f"a JSON object in a string{where}"


@dataclass(frozen=True)
class ListOf:
    """A one-dimensional array attribute, each value accepted by ``item``."""

    item: object  # a rule: Text, Range, ...
    distinct: bool = False
    nonempty: bool = False

    def accepts(self, value) -> bool:
        return (
            isinstance(value, list)
            and (bool(value) or not self.nonempty)
            and all(self.item.accepts(v) for v in value)
            and (not self.distinct or len(set(value)) == len(value))
        )

    def expected(self) -> str:
        what = "a non-empty list" if self.nonempty else "a list"
        return (
            f"{what} of {'distinct ' if self.distinct else ''}values, each {self.item.expected()}"
        )


_INDEX = Range(0, 2**63, "an integer", high_open=True)
_NS = Range(0, 1e9, "nanoseconds", low_open=True)  # at most a second (a rotation: 0.2 s)
_US = Range(0, 1e9, "microseconds", low_open=True)
_DEGREES = Range(-360, 360, "degrees")
_NAMES = ListOf(Text(), distinct=True, nonempty=True)

# Every attribute a reader parses, generated or converted, and what it must hold (decoded:
# numbers as Python numbers, string arrays as lists, JSON strings as objects). The reader
# (simlidar.dataset.reader.check_attributes) and verify check a split's attributes against
# these rules before anything uses them; an attribute not listed here is never read.
ATTRIBUTES = {
    "dataset_version": Text(r"\d{1,9}\.\d{1,9}\.\d{1,9}", "a version MAJOR.MINOR.PATCH"),
    "simlidar_version": Text(),
    "source": Choice(tuple(SOURCES)),
    "split": Choice(SPLITS),
    "config": JsonObject(),
    "seed": _INDEX,
    "noise": Range(0, 1, "a level"),
    "classes": Range(1, 2**31, "an integer"),
    "class_mode": Text(),
    "class_names": _NAMES,
    "layout_names": _NAMES,
    "object_names": _NAMES,
    "surface_names": _NAMES,
    "sensor": JsonObject(),
    "catalog": JsonObject(),
    "catalog_sha256": Text(),
    "row_laser_ids": ListOf(_INDEX, nonempty=True),
    "row_elevation_deg": ListOf(_DEGREES, nonempty=True),
    "column_azimuth_deg": ListOf(_DEGREES, nonempty=True),
    "tof_max_ns": _NS,
    "delay_unit_ns": _NS,
    "time_window_us": _US,
    "no_return_delay": Range(0, 1, "a delay"),
    "min_object_hits": Range(0, 2**31, "an integer"),
    "profile": Text(),
    "noise_on": Choice(("all", "returns")),
    "input_spikes": Choice(("all", "returns")),
    "timing": Choice(("flash", "scan")),
    "receiver": JsonObject(("name", "model")),
    "receiver_sha256": Text(),
    "materials": JsonObject(),
    "materials_sha256": Text(),
    "return_mode": Choice(RETURN_MODES),
    "beam_samples": Range(1, 2**31, "an integer"),
    "waveform_bin_ns": Range(0, 4, "ns", low_open=True),
    "waveform_bins": Range(1, 2**31, "an integer"),
    "shard": Range(0, 2**31, "an integer"),
    "shards": Range(1, 2**31, "an integer"),
    "input_sha256": Text(),
    "simulated_from": JsonObject(("sweep", "sensor_model")),
    "frames_without_objects": ListOf(_INDEX),
    "motion": JsonObject(),
    "motion_sha256": Text(),
    "rotations": Range(1, 2**31, "an integer"),
    "rotation_us": _US,
    "span_us": _US,
    "scenario_names": _NAMES,
    "scenarios": JsonObject(),
}

# The attributes a split of each source always carries besides REQUIRED_ATTRS (its card
# reads them)
SOURCE_ATTRS = {
    GENERATOR: ("classes", "layout_names", "object_names", "catalog", "catalog_sha256"),
    **{name: source.attrs for name, source in CONVERTED.items()},
}

# Converted real data (simlidar.convert), by the split's `source` attribute: name -> (dtype,
# shape), a shape's letters being N samples, E events, H rows, W columns (each source's module:
# simlidar.dataset.kitti, simlidar.dataset.dvs_barrel)
CONVERTED_SCHEMAS: dict[str, dict[str, tuple[str, tuple]]] = {
    name: source.schema for name, source in CONVERTED.items()
}


def reported_returns(attrs) -> int:
    """The returns a pulse of a generated split reports in its ``returns_*`` datasets, by its
    ``return_mode`` attribute: 2 in dual mode, 1 in the others, 0 where it has none."""
    mode = attrs.get("return_mode")
    return 0 if mode is None else 2 if mode == "dual" else 1


def in_motion(attrs) -> bool:
    """Whether a generated split (its decoded attributes) is of a dataset in motion: its
    configuration holds one of :data:`MOTION_CONFIG_KEYS`."""
    config = attrs.get("config")
    return isinstance(config, dict) and bool(MOTION_CONFIG_KEYS & config.keys())


def generated_schema(
    timing: str = "flash",
    receiver: bool = False,
    returns: int = 0,
    waveform_bins: int = 0,
    motion: bool = False,
) -> dict[str, tuple[str, object]]:
    """:data:`SCHEMA`, with :data:`SCAN_SCHEMA` under scan timing, :data:`RECEIVER_SCHEMA`
    under a receiver, :data:`RETURNS_SCHEMA` where a pulse reports ``returns`` > 0 returns,
    :data:`WAVEFORM_SCHEMA` where it keeps ``waveform_bins`` > 0 samples of its waveform (their
    trailing shapes then given H and W alone) and :data:`MOTION_SCHEMA` in ``motion``."""
    schema = (
        SCHEMA | (SCAN_SCHEMA if timing == "scan" else {}) | (RECEIVER_SCHEMA if receiver else {})
    )
    schema |= MOTION_SCHEMA if motion else {}
    if returns:
        schema |= {
            name: (dtype, lambda h, w, tail=tail: tail(h, w, returns))
            for name, (dtype, tail) in RETURNS_SCHEMA.items()
        }
    if waveform_bins:
        schema |= {
            name: (dtype, lambda h, w, tail=tail: tail(h, w, waveform_bins))
            for name, (dtype, tail) in WAVEFORM_SCHEMA.items()
        }
    return schema


def generated_shapes(
    height: int,
    width: int,
    timing: str = "flash",
    receiver: bool = False,
    returns: int = 0,
    waveform_bins: int = 0,
    motion: bool = False,
) -> dict[str, tuple[str, tuple]]:
    """name -> (dtype, trailing shape) of a generated split of ``height`` rows (the sensor's
    beams) and ``width`` columns, of ``timing`` "flash" or "scan", with a receiver or not,
    ``returns`` reported returns a pulse (0: none stored), ``waveform_bins`` samples of its
    waveform (0: none stored), in ``motion`` or not."""
    return {
        name: (dtype, tail(height, width))
        for name, (dtype, tail) in generated_schema(
            timing, receiver, returns, waveform_bins, motion
        ).items()
    }


def split_source(attrs) -> str:
    """The ``source`` of a split from its attributes; the generator's files carry none."""
    value = attrs.get("source", GENERATOR)
    try:
        return value.decode() if isinstance(value, bytes) else value
    except UnicodeDecodeError:  # the ATTRIBUTES rule names it
        return value


def expected_shapes(
    source: str,
    n: int,
    h: int,
    w: int,
    e: int = 0,
    timing: str = "flash",
    receiver: bool = False,
    returns: int = 0,
    waveform_bins: int = 0,
    motion: bool = False,
    rotations: int = 0,
) -> dict[str, tuple]:
    """name -> (dtype, full shape) of every dataset a split of ``source`` must hold
    (``timing``: a generated split's ``timing`` attribute, "flash" where it has none;
    ``receiver``: whether it has a ``receiver`` attribute; ``returns``: its
    :func:`reported_returns`; ``waveform_bins``: its attribute of that name, 0 where it has
    none; ``motion``: :func:`in_motion`).

    source : the split's ``source``: ``GENERATOR`` or a key of :data:`CONVERTED_SCHEMAS` (any
        other is a DatasetError)
    n : the split's samples (N)
    h, w : a sample's rows (H: a generated split's beams) and columns (W)
    e : the split's events (E), the rows of a converted split's per-event datasets; 0 where it
        has none
    rotations : a stream split's rotations (R, its attribute ``rotations``); 0 for the others
    """
    if source == GENERATOR:
        shapes = generated_shapes(h, w, timing, receiver, returns, waveform_bins, motion)
        return {name: (dtype, (n, *tail)) for name, (dtype, tail) in shapes.items()}
    if source not in CONVERTED_SCHEMAS:
        known = ", ".join([GENERATOR, *CONVERTED_SCHEMAS])
        raise DatasetError(f"source {source!r}: expected one of {known}")
    dims = {"N": n, "E": e, "H": h, "W": w, "R": rotations}
    return {
        name: (dtype, tuple(dims.get(d, d) for d in shape))
        for name, (dtype, shape) in CONVERTED[source].schema_of(receiver).items()
    }
