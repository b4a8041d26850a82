"""Full sweeps: every firing of whole rotations of a sensor over a scene (``simlidar sweep``).

A *frame* is one rotation: :func:`~simlidar.sensor.rays.cycles_per_rotation` firing cycles
(1808 for a VLP-16 at 600 RPM), each firing every laser, so a frame holds H x C pulses (28,928
for the VLP-16, 133,312 for the HDL-64E). Cycle ``k`` of a frame starts at azimuth
``-180 + (k + phase) * azimuth_step_deg``: behind the sensor, turning clockwise (right) through
the front, as a Velodyne frame packet stream does. Frame ``f`` shows the scene of class
``f mod classes`` (the window generator's labelling) drawn from its own random stream,
``SeedSequence(seed, spawn_key=(2, f))``: one draw of the rotation phase and the scene's
parameters, without the window generator's redraws (the shipped scenes put their object ahead,
where every frame sees it: ``object_points`` counts its returns).

Each pulse keeps its quantised range (NaN: no return), the surface it hit (a per-point label:
segmentation), an intensity proxy (``|cos|`` of the angle of incidence: real intensities also
depend on the surface's reflectivity, which the scenes do not model) and, shared by every
frame, its emission time within the rotation. :func:`frame_points` turns a frame into a point
cloud in the sensor's frame (x forward, y left, z up, origin at the rotation axis' reference
point: KITTI's velodyne frame), and :func:`export_frame` writes it as KITTI ``.bin`` (with a
SemanticKITTI-style ``.label`` of surfaces), PLY or PCD. The file format: docs/sweeps.md.

The scenes were written for a window ahead of the sensor: behind it the road ends 0-10 m back
(``entry_m`` of the tunnel, the road box of every layout), so the rear half of a frame sees
little. That is the catalog's extent, not the sweep's.
"""

import json
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from simlidar import __version__
from simlidar.atomic import building
from simlidar.dataset.writer import SplitWriter
from simlidar.errors import ConfigError
from simlidar.generator.config import GeneratorConfig
from simlidar.generator.pulses import quantise_range
from simlidar.generator.simulate import FIXED_COLUMNS, class_plan, factors, sample_stream
from simlidar.scene.build import build_batch
from simlidar.scene.recipe import Catalog
from simlidar.sensor.model import Sensor, row_order
from simlidar.sensor.raycast import MAX_BATCH, cast
from simlidar.sensor.rays import cycles_per_rotation, sweep_emission_ns, sweep_rays
from simlidar.settings import Range, check, setting

SWEEP_VERSION = "1.1.0"  # 1.1.0: the catalog's sensor variants (HDL-64E frames changed)
SWEEP_FILE = "frames.h5"
FRAME_BATCH = 16  # frames ray-cast together (does not change the files)
MAX_FRAMES = 10**6
EXPORTS = ("kitti", "ply", "pcd")
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


@dataclass(frozen=True)
class SweepConfig:
    """What a sweep file holds beyond the scenes' settings (a GeneratorConfig's classes,
    seed, variation and sensor)."""

    frames: int = setting(
        10,
        "Frames: full rotations of the sensor; frame f shows class f mod classes.",
        Range(1, MAX_FRAMES, "an integer"),
    )

    def __post_init__(self) -> None:
        check(self)


@dataclass(frozen=True)
class Frames:
    """A block of consecutive frames (n frames, H lasers in rows, C cycles)."""

    range_m: np.ndarray  # (n, H, C) float32, quantised; NaN: no return
    surface: np.ndarray  # (n, H, C) uint8, 0: no return
    intensity: np.ndarray  # (n, H, C) float32, |cos incidence|, 0: no return
    labels: np.ndarray  # (n,) int64
    layout: np.ndarray  # (n,) uint8
    object: np.ndarray  # (n,) uint8
    object_pose: np.ndarray  # (n, 3) float32: x_m, y_m, yaw_deg; NaN without object
    # (n, 7) float32: the object's box, length_m, width_m, height_m along its yaw, and its
    # bottom centre x_m, y_m, z_m in the scene frame, yaw_deg; NaN without object
    object_box: np.ndarray
    object_points: np.ndarray  # (n,) int32, returns from the labelled object
    phase: np.ndarray  # (n,) float64, rotation phase in azimuth steps


SHAPES = {  # name -> (dtype, trailing shape given H and C)
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


def simulate_frames(config: GeneratorConfig, catalog: Catalog, start: int, stop: int) -> Frames:
    """Frames ``start .. stop - 1`` of a sweep of ``config``'s sensor and scenes (its classes,
    seed and variation; at most MAX_BATCH frames)."""
    if not 0 < stop - start <= MAX_BATCH:
        raise ConfigError(f"batch of {stop - start} frames: expected 1..{MAX_BATCH}")
    sensor = config.sensor
    catalog = catalog.for_sensor(sensor.name).with_variation(config.variation)
    plan = class_plan(catalog, config.classes)
    index = np.arange(start, stop)
    labels = index % plan.classes
    streams = [sample_stream(config.seed, "sweep", i) for i in index]
    free = np.stack([g.random(2) for g in streams])
    layout, obj = factors(plan, labels, free, len(catalog.layouts), len(catalog.objects))
    lc = catalog.layout_columns
    u = np.stack([g.random(FIXED_COLUMNS + lc + catalog.object_columns) for g in streams])
    origins, directions = sweep_rays(sensor, u[:, 0])
    scene = build_batch(
        catalog,
        layout,
        obj,
        u[:, FIXED_COLUMNS : FIXED_COLUMNS + lc],
        u[:, FIXED_COLUMNS + lc :],
    )
    hits = cast(scene, origins, directions, index % MAX_BATCH, sensor.max_range_m, incidence=True)
    r = quantise_range(hits.range_m, sensor)
    returned = ~np.isnan(r)
    return Frames(
        range_m=r.astype(np.float32),
        surface=np.where(returned, hits.surface, 0).astype(np.uint8),
        intensity=np.where(returned, hits.cos_incidence, 0.0).astype(np.float32),
        labels=labels.astype(np.int64),
        layout=layout.astype(np.uint8),
        object=obj.astype(np.uint8),
        object_pose=scene.object_pose.astype(np.float32),
        object_box=object_boxes(scene).astype(np.float32),
        object_points=(hits.on_object & returned).sum(axis=(1, 2)).astype(np.int32),
        phase=u[:, 0],
    )


def object_boxes(scene) -> np.ndarray:
    """The box of each scene's object, aligned with its yaw: (B, 7) float64 length, width,
    height, bottom centre x, y, z (scene frame), yaw_deg; NaN rows where there is none."""
    boxes = np.full((scene.size, 7), np.nan)
    for i in np.unique(scene.sample[scene.is_object]):
        v = scene.triangles[scene.is_object & (scene.sample == i)].reshape(-1, 3)
        x, y, yaw = scene.object_pose[i]
        c, s = np.cos(np.deg2rad(yaw)), np.sin(np.deg2rad(yaw))
        along = c * (v[:, 0] - x) + s * (v[:, 1] - y)  # in the object's own axes
        across = -s * (v[:, 0] - x) + c * (v[:, 1] - y)
        mid_a, mid_c = (along.max() + along.min()) / 2, (across.max() + across.min()) / 2
        boxes[i] = (
            np.ptp(along),
            np.ptp(across),
            np.ptp(v[:, 2]),
            x + c * mid_a - s * mid_c,
            y + s * mid_a + c * mid_c,
            v[:, 2].min(),
            yaw,
        )
    return boxes


def sweep_name(config: GeneratorConfig, sweep: SweepConfig) -> str:
    """``simlidar-sweep-<classes>c-<sensor>-<frames>f-seed<seed>[-var<v>]-v<version>``."""
    variation = f"-var{float(config.variation)!r}" if config.variation != 1.0 else ""
    return (
        f"simlidar-sweep-{config.classes}c-{config.sensor.name}-{sweep.frames}f-seed"
        f"{config.seed}{variation}-v{SWEEP_VERSION}"
    )


def sweep(
    config: GeneratorConfig,
    sweep_config: SweepConfig,
    catalog: Catalog,
    out: str | Path,
    exports: tuple[str, ...] = (),
    force: bool = False,
    progress: bool = True,
    batch: int = FRAME_BATCH,
) -> Path:
    """Simulate ``sweep_config.frames`` frames into ``out/<sweep_name>/frames.h5`` (one frame
    a chunk), draw ``bev.png`` (:func:`draw_bev`: up to four frames) and write every frame in
    each format of ``exports`` (:data:`EXPORTS`); the folder appears complete or not at all."""
    from tqdm import tqdm

    for fmt in exports:
        if fmt not in EXPORTS:
            raise ConfigError(f"export {fmt!r}: expected one of {', '.join(EXPORTS)}")
    catalog = catalog.for_sensor(config.sensor.name)  # its fingerprint: the recipes used
    plan = class_plan(catalog, config.classes)  # a bad class count fails before any file
    sensor, n = config.sensor, sweep_config.frames
    h, c = sensor.beams, cycles_per_rotation(sensor)
    attrs = {
        "format": "simlidar-sweep",
        "sweep_version": SWEEP_VERSION,
        "simlidar_version": __version__,
        "config": config.to_json(),
        "sweep": json.dumps(asdict(sweep_config), sort_keys=True),
        "sensor": json.dumps(sensor.to_dict(), sort_keys=True),
        "catalog_sha256": catalog.fingerprint(),
        "class_names": json.dumps(list(plan.names)),
        "surface_names": json.dumps(list(catalog.surfaces)),
        "object_names": json.dumps(list(catalog.object_names)),
        "row_laser_ids": np.array(row_order(sensor), dtype=np.int32),
        "cycles": c,
    }
    shapes = {name: (dtype, tail(h, c)) for name, (dtype, tail) in SHAPES.items()}
    name = sweep_name(config, sweep_config)
    with building(out, name, force) as folder:
        writer = SplitWriter(folder / SWEEP_FILE, n, shapes, attrs, frozenset(), chunk=1)
        try:
            writer.file.create_dataset("emission_ns", data=sweep_emission_ns(sensor))
            bar = tqdm(total=n, desc="sweep", unit="frame", disable=not progress)
            for first in range(0, n, batch):
                frames = simulate_frames(config, catalog, first, min(first + batch, n))
                writer.append({name: getattr(frames, name) for name in SHAPES})
                bar.update(len(frames.labels))
            bar.close()
            writer.close()
        except BaseException:
            writer.abort()
            raise
        draw_bev(folder / SWEEP_FILE, folder / "bev.png")
        for fmt in exports:
            for f in range(n):
                export_frame(folder / SWEEP_FILE, f, folder, fmt)
    return Path(out) / name


def _check_frame(f, path: str | Path, frame: int) -> Sensor:
    """The sensor of the open sweep file ``f``; a ConfigError unless it is a sweep file that
    holds frame ``frame``."""
    if f.attrs.get("format") != "simlidar-sweep":
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
        sensor = _check_frame(f, path, frame)
        values = {name: f[name][frame] for name in SHAPES}
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


# Velodyne -> camera axes (x right, y down, z forward), no offset, no rectification: what
# `simlidar convert kitti` needs to read a sweep's boxes (simlidar simulates no camera)
KITTI_CALIB = "R0_rect: 1 0 0 0 1 0 0 0 1\nTr_velo_to_cam: 0 -1 0 0 0 0 -1 0 1 0 0 0\n"
KITTI_TYPES = {"car": "Car", "pedestrian": "Pedestrian", "truck": "Truck"}  # others: Misc


def kitti_label(path: str | Path, frame: int) -> str:
    """The KITTI object label file (label_2) of one frame: its object, if it has one, as a
    15-column line in camera coordinates (:data:`KITTI_CALIB`): type, truncated 0, occluded 0,
    alpha, a 2D box of zeros (no camera), h w l, bottom centre x y z, rotation_y."""
    import h5py

    with h5py.File(path, "r") as f:  # only what the label needs (not the frame's points)
        sensor = _check_frame(f, path, frame)
        obj = int(f["object"][frame])
        if not obj:
            return ""
        name = json.loads(f.attrs["object_names"])[obj]  # 0: none
        box = f["object_box"][frame]
    length, width, height, x, y, z, yaw = (float(v) for v in box)
    # velodyne (x forward, y left, z up from the sensor) -> camera (x right, y down, z ahead)
    cx, cy, cz = -y, -(z - sensor.mount_height_m), x
    ry = -np.deg2rad(yaw) - np.pi / 2  # a heading along +x (ahead) is rotation_y = -pi/2
    ry = (ry + np.pi) % (2 * np.pi) - np.pi
    alpha = (ry - np.arctan2(cx, cz) + np.pi) % (2 * np.pi) - np.pi
    numbers = [0, 0, alpha, 0, 0, 0, 0, height, width, length, cx, cy, cz, ry]
    return " ".join([KITTI_TYPES.get(name, "Misc")] + [f"{v:.4f}" for v in numbers]) + "\n"


def kitti_file(path: str | Path, frame: int, folder: str, points=None) -> bytes:
    """The bytes of one file of frame ``frame`` in the KITTI export (:func:`export_frame`):
    ``folder`` ``velodyne`` (float32 x, y, z, intensity), ``labels`` (uint32 surface a point),
    ``label_2`` (:func:`kitti_label`) or ``calib`` (:data:`KITTI_CALIB`). ``points``: the
    frame's :func:`frame_points`, if already made."""
    if folder == "label_2":
        return kitti_label(path, frame).encode()
    if folder == "calib":
        return KITTI_CALIB.encode()
    points = frame_points(path, frame) if points is None else points
    if folder == "velodyne":
        xyzi = np.stack([points[k] for k in ("x", "y", "z", "intensity")], axis=1)
        return xyzi.astype("<f4").tobytes()
    if folder == "labels":
        return points["surface"].astype("<u4").tobytes()
    raise ConfigError(f"KITTI folder {folder!r}: expected velodyne, labels, label_2 or calib")


_PLY_TYPES = {"<f4": "float", "u1": "uchar", "<f8": "double"}
_PCD_TYPES = {"<f4": ("4", "F"), "u1": ("1", "U"), "<f8": ("8", "F")}


def export_frame(path: str | Path, frame: int, out: str | Path, fmt: str) -> list[Path]:
    """Write frame ``frame`` of a sweep file under ``out`` as ``fmt``: ``kitti``
    (``velodyne/NNNNNN.bin``: float32 x, y, z, intensity, KITTI's layout;
    ``labels/NNNNNN.label``: uint32 surface index a point, SemanticKITTI's; and the object
    benchmark's ``label_2/NNNNNN.txt`` and ``calib/NNNNNN.txt``, :func:`kitti_label`, so that
    ``simlidar convert kitti`` reads the folder), ``ply``
    (``ply/NNNNNN.ply``, binary little endian, every field of :data:`POINT_DTYPE`) or ``pcd``
    (``pcd/NNNNNN.pcd``, PCD 0.7 binary, the same fields). Returns the files written."""
    points = frame_points(path, frame)
    out, stem = Path(out), f"{frame:06d}"
    if fmt == "kitti":
        folders = {"velodyne": ".bin", "labels": ".label", "label_2": ".txt", "calib": ".txt"}
        files = [out / folder / f"{stem}{suffix}" for folder, suffix in folders.items()]
        blobs = [kitti_file(path, frame, folder, points) for folder in folders]
    elif fmt == "ply":
        header = ["ply", "format binary_little_endian 1.0", f"element vertex {len(points)}"]
        header += [
            f"property {_PLY_TYPES[POINT_DTYPE[k].str.lstrip('|')]} {k}" for k in POINT_DTYPE.names
        ]
        files = [out / "ply" / f"{stem}.ply"]
        blobs = ["\n".join([*header, "end_header"]).encode() + b"\n" + points.tobytes()]
    elif fmt == "pcd":
        kinds = [_PCD_TYPES[POINT_DTYPE[k].str.lstrip("|")] for k in POINT_DTYPE.names]
        header = [
            "# .PCD v0.7 - Point Cloud Data file format",
            "VERSION 0.7",
            "FIELDS " + " ".join(POINT_DTYPE.names),
            "SIZE " + " ".join(size for size, _ in kinds),
            "TYPE " + " ".join(kind for _, kind in kinds),
            "COUNT " + " ".join("1" for _ in kinds),
            f"WIDTH {len(points)}",
            "HEIGHT 1",
            "VIEWPOINT 0 0 0 1 0 0 0",
            f"POINTS {len(points)}",
            "DATA binary",
        ]
        files = [out / "pcd" / f"{stem}.pcd"]
        blobs = ["\n".join(header).encode() + b"\n" + points.tobytes()]
    else:
        raise ConfigError(f"export {fmt!r}: expected one of {', '.join(EXPORTS)}")
    for file, blob in zip(files, blobs):
        file.parent.mkdir(parents=True, exist_ok=True)
        file.write_bytes(blob)
    return files


def draw_bev(
    path: str | Path, out: str | Path, frames: list[int] | None = None, reach_m: float = 40.0
) -> Path:
    """Bird's-eye views of frames ``frames`` of a sweep file, points coloured by surface,
    written as a PNG. Default: up to four frames of different layouts, with objects, as
    varied as the file has (:func:`_varied_frames`)."""
    import h5py
    from matplotlib import colormaps
    from matplotlib.figure import Figure

    with h5py.File(path, "r") as f:
        names = json.loads(f.attrs["surface_names"])
        classes = json.loads(f.attrs["class_names"])
        labels = f["labels"][:]
        layout, obj = f["layout"][:], f["object"][:]
    frames = _varied_frames(layout, obj) if frames is None else frames
    fig = Figure(figsize=(3.0 * len(frames), 4.0))
    palette = colormaps["tab20"]
    for k, frame in enumerate(frames):
        points = frame_points(path, frame)
        ax = fig.add_subplot(1, len(frames), k + 1)
        for s in sorted(set(points["surface"].tolist())):
            mine = points[points["surface"] == s]
            # x forward is up the picture, y left is left
            size = 0.4 if len(mine) > 1000 else 3.0  # small things (objects, lamps) larger
            ax.scatter(
                -mine["y"], mine["x"], s=size, color=palette(s % 20), label=names[s], linewidths=0
            )
        ax.set_xlim(-reach_m, reach_m)
        ax.set_ylim(-reach_m / 2, reach_m * 2)
        ax.set_aspect("equal")
        ax.set_title(f"frame {frame}: {classes[labels[frame]]}", fontsize=8)
        ax.tick_params(labelsize=6)
        ax.legend(fontsize=5, markerscale=10, loc="lower left")
    fig.supxlabel("right of the sensor (m)", fontsize=8)
    fig.supylabel("ahead of the sensor (m)", fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    return Path(out)


def _varied_frames(layout: np.ndarray, obj: np.ndarray, most: int = 4) -> list[int]:
    """Up to ``most`` frames of different layouts: first those that also bring a new object,
    then any with a new layout and an object, then any frame, in frame order."""
    chosen: list[int] = []
    rules = [
        lambda f: obj[f] and obj[f] not in obj[chosen],
        lambda f: bool(obj[f]),
        lambda f: True,
    ]
    for rule in rules:
        for f in range(len(layout)):
            if len(chosen) < most and layout[f] not in layout[chosen] and rule(f):
                chosen.append(f)
    return sorted(chosen)
