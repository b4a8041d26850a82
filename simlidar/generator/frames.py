"""A sweep's frames file read back (``frames.h5``, :mod:`simlidar.generator.sweep`): one
frame's values, and its returns as a point cloud in the sensor's frame (x forward, y left, z up,
origin at the rotation axis' reference point: KITTI's velodyne frame), whose fields are
:data:`~simlidar.dataset.schema.POINT_DTYPE`. The file format: docs/sweeps.md.
"""

import json
from pathlib import Path

import numpy as np

from simlidar.dataset.schema import POINT_DTYPE, SWEEP_FILE, SWEEP_FORMAT, SWEEP_SCHEMA
from simlidar.errors import ConfigError
from simlidar.sensor.model import Sensor, row_order
from simlidar.sensor.rays import sweep_rays


def check_frame(f, path: str | Path, frame: int) -> Sensor:
    """The sensor of the open sweep file ``f``; a ConfigError unless it is a sweep file that
    holds frame ``frame``."""
    if f.attrs.get("format") != SWEEP_FORMAT:
        raise ConfigError(f"{path}: expected a simlidar sweep file ({SWEEP_FILE})")
    count = f["labels"].shape[0]
    if not 0 <= frame < count:
        raise ConfigError(f"frame {frame}: expected 0 to {count - 1} ({path})")
    return Sensor.from_dict(json.loads(f.attrs["sensor"]))


def read_frame(path: str | Path, frame: int) -> tuple[Sensor, dict, np.ndarray]:
    """The sensor, the per-frame values and the emission times of frame ``frame`` of a sweep
    file."""
    import h5py

    with h5py.File(path, "r") as f:
        sensor = check_frame(f, path, frame)
        values = {name: f[name][frame] for name in SWEEP_SCHEMA}
        return sensor, values, f["emission_ns"][:]


def frame_points(path: str | Path, frame: int) -> np.ndarray:
    """The returns of one frame as a point cloud (:data:`POINT_DTYPE`), in firing order, in
    the sensor's frame (x forward, y left, z up from the rotation axis' reference point):
    position, intensity proxy, surface label, laser id and emission time (ns from the
    rotation's first firing)."""
    sensor, values, emission = read_frame(path, frame)
    origins, directions = sweep_rays(sensor, np.array([values["phase"]]))
    r = values["range_m"].astype(np.float64)
    order = np.argsort(emission, axis=None, kind="stable")  # firing order
    keep = order[~np.isnan(r.reshape(-1)[order])]
    xyz = (
        origins[0].reshape(-1, 3)[keep]
        + r.reshape(-1)[keep, None] * directions[0].reshape(-1, 3)[keep]
    )
    xyz[:, 2] -= sensor.mount_height_m
    points = np.empty(len(keep), POINT_DTYPE)
    points["x"], points["y"], points["z"] = xyz.T
    points["intensity"] = values["intensity"].reshape(-1)[keep]
    points["surface"] = values["surface"].reshape(-1)[keep]
    lasers = np.asarray(row_order(sensor), dtype=np.uint8)
    points["laser"] = np.broadcast_to(lasers[:, None], r.shape).reshape(-1)[keep]
    points["t_ns"] = emission.reshape(-1)[keep]
    return points
