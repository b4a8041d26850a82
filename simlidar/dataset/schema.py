"""The split files' schemas: what every generated or converted split holds.

Every dataset and attribute is described in ``docs/dataset-format.md`` (the generator's) and
``docs/converters.md`` (converted real data); keep them in step.
"""

from simlidar.dataset.version import GENERATOR
from simlidar.errors import DatasetError

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
# The shuffle filter helps gzip on the noisy delays (random mantissas) and hurts it on the
# quantised clean delays and times of flight (measured: smaller and faster without it).
SHUFFLED = {"delays", "phase", "shift", "object_pose"}
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

# Converted real data (simlidar.convert), by the split's `source` attribute:
# name -> (dtype, shape), a shape's letters being N samples, E events, H rows, W columns.
CONVERTED_SCHEMAS: dict[str, dict[str, tuple[str, tuple]]] = {
    "kitti": {
        "delays": ("float32", ("N", "H", "W")),
        "labels": ("int64", ("N",)),
        "frame": ("int64", ("N",)),
        "crop_origin": ("int32", ("N", 2)),
        "box_corners_m": ("float32", ("N", 8, 3)),
        "box_points": ("int32", ("N",)),
        "truncated": ("float32", ("N",)),
        "occluded": ("uint8", ("N",)),
    },
    "dvs-barrel": {
        "delays": ("float32", ("N", "H", "W")),
        "labels": ("int64", ("N",)),
        "recording": ("int64", ("N",)),
        "event_start": ("int64", ("N",)),
        "event_count": ("int64", ("N",)),
        "event_x": ("uint8", ("E",)),
        "event_y": ("uint8", ("E",)),
        "event_p": ("int8", ("E",)),
        "event_t_us": ("int64", ("E",)),
    },
}


def generated_schema(timing: str = "flash") -> dict[str, tuple[str, object]]:
    """:data:`SCHEMA`, and :data:`SCAN_SCHEMA` under scan timing."""
    return SCHEMA | SCAN_SCHEMA if timing == "scan" else SCHEMA


def generated_shapes(
    height: int, width: int, timing: str = "flash"
) -> dict[str, tuple[str, tuple]]:
    """name -> (dtype, trailing shape) of a generated split of ``height`` rows (the sensor's
    beams) and ``width`` columns, of ``timing`` "flash" or "scan"."""
    return {
        name: (dtype, tail(height, width))
        for name, (dtype, tail) in generated_schema(timing).items()
    }


def split_source(attrs) -> str:
    """The ``source`` of a split from its attributes; the generator's files carry none."""
    value = attrs.get("source", GENERATOR)
    return value.decode() if isinstance(value, bytes) else value


def expected_shapes(
    source: str, n: int, h: int, w: int, e: int = 0, timing: str = "flash"
) -> dict[str, tuple]:
    """name -> (dtype, full shape) of every dataset a split of ``source`` must hold
    (``timing``: a generated split's ``timing`` attribute, "flash" where it has none)."""
    if source == GENERATOR:
        shapes = generated_shapes(h, w, timing)
        return {name: (dtype, (n, *tail)) for name, (dtype, tail) in shapes.items()}
    if source not in CONVERTED_SCHEMAS:
        known = ", ".join([GENERATOR, *CONVERTED_SCHEMAS])
        raise DatasetError(f"source {source!r}: expected one of {known}")
    dims = {"N": n, "E": e, "H": h, "W": w}
    return {
        name: (dtype, tuple(dims.get(d, d) for d in shape))
        for name, (dtype, shape) in CONVERTED_SCHEMAS[source].items()
    }
