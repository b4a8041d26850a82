"""A sweep's frames file read back (``frames.h5``, :mod:`simlidar.generator.sweep`): one
frame's values, and its returns as a point cloud in the sensor's frame (x forward, y left, z up,
origin at the rotation axis' reference point: KITTI's velodyne frame), whose fields are
:data:`~simlidar.dataset.schema.POINT_DTYPE`. The file format: docs/sweeps.md.
"""

import json
from pathlib import Path

import numpy as np

from simlidar.dataset.schema import (
    POINT_DTYPE,
    RETURN_POINT_DTYPE,
    SWEEP_FILE,
    SWEEP_FORMAT,
    reported_returns,
    sweep_schema,
)
from simlidar.errors import ConfigError
from simlidar.motion.poses import PlanarMotion, Poses
from simlidar.motion.trajectory import Trajectory
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
    """The sensor, the per-frame values (every dataset of the file's schema, the reported
    returns too where it stores them) and the emission times of frame ``frame`` of a sweep
    file."""
    import h5py

    with h5py.File(path, "r") as f:
        sensor = check_frame(f, path, frame)
        schema = sweep_schema(reported_returns(dict(f.attrs)), "sequence_frames" in f.attrs)
        values = {name: f[name][frame] for name in schema}
        return sensor, values, f["emission_ns"][:]


def frame_points(path: str | Path, frame: int) -> np.ndarray:
    """The returns of one frame as a point cloud (:data:`POINT_DTYPE`), in firing order, in
    the sensor's frame (x forward, y left, z up from the rotation axis' reference point):
    position, intensity (the receiver's byte, or the |cos| proxy), surface label, laser id and
    emission time (ns from the rotation's first firing). A sweep that stores every reported
    return (``returns_*``) gives one point a distinct return (:data:`RETURN_POINT_DTYPE`), a
    pulse's in order of arrival, numbered from 1, with its count of returns (an echo reported
    twice, dual mode's single echo, is one point)."""
    sensor, values, emission = read_frame(path, frame)
    origins, directions = sweep_rays(sensor, np.array([values["phase"]]))
    if "returns_range_m" in values:
        slots = values["returns_range_m"].shape[-1]
        r = values["returns_range_m"].reshape(-1, slots).astype(np.float64)
        intensity = values["returns_intensity"].reshape(-1, slots)
        surface = values["returns_surface"].reshape(-1, slots)
    else:
        r = values["range_m"].reshape(-1, 1).astype(np.float64)
        intensity = values["intensity"].reshape(-1, 1)
        surface = values["surface"].reshape(-1, 1)
    # an echo reported twice (the same range in two slots) is one return
    for k in range(1, r.shape[1]):
        same = (r[:, :k] == r[:, k : k + 1]).any(axis=1)
        r[same, k] = np.nan
    arrival = np.argsort(np.where(np.isnan(r), np.inf, r), axis=1, kind="stable")
    r, intensity, surface = (
        np.take_along_axis(a, arrival, axis=1) for a in (r, intensity, surface)
    )
    counts = (~np.isnan(r)).sum(axis=1)
    order = np.argsort(emission, axis=None, kind="stable")  # firing order
    pulse = np.repeat(order, counts[order])
    slot = np.arange(len(pulse)) - np.repeat(
        np.cumsum(counts[order]) - counts[order], counts[order]
    )
    distances = r[pulse, slot]
    xyz = (
        origins[0].reshape(-1, 3)[pulse] + distances[:, None] * directions[0].reshape(-1, 3)[pulse]
    )
    xyz[:, 2] -= sensor.mount_height_m
    returns = "returns_range_m" in values
    points = np.empty(len(pulse), RETURN_POINT_DTYPE if returns else POINT_DTYPE)
    points["x"], points["y"], points["z"] = xyz.T
    points["intensity"] = intensity[pulse, slot]
    points["surface"] = surface[pulse, slot]
    lasers = np.asarray(row_order(sensor), dtype=np.uint8)
    shape = values["range_m"].shape
    points["laser"] = np.broadcast_to(lasers[:, None], shape).reshape(-1)[pulse]
    points["t_ns"] = emission.reshape(-1)[pulse]
    if returns:
        points["return_number"] = slot + 1
        points["number_of_returns"] = counts[pulse]
    return points


def deskewed_xyz(path: str | Path, frame: int, points: np.ndarray | None = None) -> np.ndarray:
    """The points of frame ``frame`` (:func:`frame_points`, made if not given) in the sensor's
    frame at the frame's reference time (its middle cycle, the head facing ahead; its
    ``ego_pose``): each point moved by the ego's motion between its own emission time and
    that time, as KISS-ICP deskews (``p* = Exp(s w) p + s v`` for constant velocity), here
    exactly: each pulse's pose is the ego's closed-form motion at its time
    (:class:`~simlidar.motion.poses.PlanarMotion`). A sweep that does not move returns the
    points as they are. (P, 3) float64."""
    import h5py

    points = frame_points(path, frame) if points is None else points
    xyz = np.stack([points[k].astype(np.float64) for k in ("x", "y", "z")], axis=-1)
    with h5py.File(path, "r") as f:
        sensor = check_frame(f, path, frame)
        if "ego_pose" not in f:
            return xyz
        config = json.loads(f.attrs["config"])
        start_ns, pose = float(f["start_ns"][frame]), f["ego_pose"][frame]
        rows = f["ego_trajectory"][:] if "ego_trajectory" in f else None
    if rows is not None:  # the file's own poses: t, x, y, z, then the quaternion
        ego = Trajectory.from_rows(rows, f"{path}: ego_trajectory")
    else:
        ego = PlanarMotion(config.get("ego_speed_mps", 0.0), config.get("ego_yaw_rate_deg_s", 0.0))
    mount = np.array([0.0, 0.0, sensor.mount_height_m])  # the rays' frame stands on the road
    at_pulse = ego.poses((start_ns + points["t_ns"]) * 1e-9).to_scene(xyz + mount)
    return Poses(pose[:, :3], pose[:, 3]).to_body(at_pulse) - mount
