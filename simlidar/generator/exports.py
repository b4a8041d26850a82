"""A sweep's frames as point-cloud files (``simlidar sweep --export``): KITTI ``.bin`` with a
SemanticKITTI-style ``.label`` of surfaces and the object benchmark's label and calibration
files (so that ``simlidar convert kitti`` reads the folder), PLY or PCD; for a sweep in motion
(its frames store ``ego_pose``) also KITTI odometry's ``poses.txt``, KITTI tracking's
``label_02/SSSS.txt`` and an instance id in the ``.label`` files. The file formats:
docs/sweeps.md.
"""

import json
from pathlib import Path

import numpy as np

from simlidar.dataset.kitti import LABEL_COLUMNS, SCAN_DTYPE
from simlidar.dataset.schema import MOTION_POINT_FIELDS
from simlidar.errors import ConfigError, DatasetError, shown
from simlidar.generator.frames import check_frame, deskewed_xyz, frame_points
from simlidar.motion.poses import Poses

EXPORTS = ("kitti", "ply", "pcd")

# Velodyne -> camera axes (x right = -y, y down = -z, z ahead = x), no offset, no
# rectification: what `simlidar convert kitti` needs to read a sweep's boxes (simlidar
# simulates no camera, so the camera sits at the velodyne's origin)
VELO_TO_CAM = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
KITTI_CALIB = "R0_rect: 1 0 0 0 1 0 0 0 1\nTr_velo_to_cam: {}\n".format(
    " ".join(f"{v:g}" for v in np.hstack([VELO_TO_CAM, np.zeros((3, 1))]).ravel())
)
KITTI_TYPES = {"car": "Car", "pedestrian": "Pedestrian", "truck": "Truck"}  # others: Misc
POSES_FILE = "poses.txt"  # KITTI odometry's poses/SS.txt, one file for the sweep's frames
TRACKING_FOLDER = "label_02"  # KITTI tracking's labels, one file a sequence
# SemanticKITTI's .label: the semantic label in the lower 16 bits, the instance id above
INSTANCE_SHIFT = 16
OBJECT_INSTANCE = 1  # one labelled object a scene; 0: no instance (stuff, or no object)


def sensor_poses(f, sensor, frames) -> Poses | None:
    """The sensor's poses in the scene frame at the reference times of ``frames`` (an index or
    a slice of the open sweep file ``f``'s frames): KITTI's velodyne frame, whose origin is
    ``mount_height_m`` above the rig's, so the rig's ``ego_pose`` composed with that offset,
    exactly (a rig that pitches carries its sensor off the vertical). None for a sweep that
    does not move: its sensor stands ``mount_height_m`` above the scene's origin, unturned.
    Shapes: (3, 3) and (3,) for one frame, (n, 3, 3) and (n, 3) for a slice."""
    if "ego_pose" not in f:
        return None
    pose = np.asarray(f["ego_pose"][frames], dtype=np.float64)
    rig = Poses(pose[..., :3], pose[..., 3])
    mount = np.broadcast_to([0.0, 0.0, sensor.mount_height_m], rig.translation_m.shape)
    return Poses(rig.rotation, rig.to_scene(mount))


def sequence_frames(f, path: str | Path) -> int:
    """The frames of one sequence of the open sweep file ``f`` in motion, its attribute
    ``sequence_frames``, L: sequence s is frames s L to s L + L - 1 (the last one may end
    early). Read from the attribute, not from each frame's ``sequence``, so that a frame's
    sequence costs no read of the others' (one HDF5 chunk a frame)."""
    length = f.attrs.get("sequence_frames")
    if isinstance(length, np.integer | int) and not isinstance(length, bool) and length >= 1:
        return int(length)
    raise DatasetError(f"{path}: sequence_frames={shown(length)}, expected a whole number >= 1")


def _label_line(name: str, box: np.ndarray, sensor, pose: Poses | None) -> str:
    """The 15 columns of :func:`kitti_label` (with the newline) of an object ``name`` whose
    ``object_box`` (7,) is in the scene frame, seen from the sensor at ``pose``
    (:func:`sensor_poses`)."""
    length, width, height, x, y, z, yaw = (float(v) for v in box)
    if pose is None:  # the sensor mount_height_m above the scene's origin
        z -= sensor.mount_height_m
    else:  # its box's centre and heading in the frame's own sensor frame; KITTI's boxes turn
        # about the vertical only, so a rig's roll and pitch leave the box upright
        x, y, z = (float(v) for v in pose.to_body(np.array([x, y, z])))
        yaw -= float(np.degrees(np.arctan2(pose.rotation[1, 0], pose.rotation[0, 0])))
    # velodyne (x forward, y left, z up from the sensor) -> camera (x right, y down, z ahead)
    cx, cy, cz = -y, -z, x
    ry = -np.deg2rad(yaw) - np.pi / 2  # a heading along +x (ahead) is rotation_y = -pi/2
    ry = (ry + np.pi) % (2 * np.pi) - np.pi
    alpha = (ry - np.arctan2(cx, cz) + np.pi) % (2 * np.pi) - np.pi
    given = {"alpha": alpha, "h": height, "w": width, "l": length, "x": cx, "y": cy, "z": cz}
    given["rotation_y"] = ry
    numbers = [given.get(column, 0) for column in LABEL_COLUMNS[1:]]  # the others: 0
    return " ".join([KITTI_TYPES.get(name, "Misc")] + [f"{v:.4f}" for v in numbers]) + "\n"


def kitti_label(path: str | Path, frame: int) -> str:
    """The KITTI object label file (label_2) of one frame: its object, if it has one, as a
    15-column line in camera coordinates (:data:`KITTI_CALIB`) of the frame's own sensor (in
    motion: its pose at the frame's reference time, where ``object_box`` is): type, truncated
    0, occluded 0, alpha, a 2D box of zeros (no camera), h w l, bottom centre x y z,
    rotation_y."""
    import h5py

    with h5py.File(path, "r") as f:  # only what the label needs (not the frame's points)
        sensor = check_frame(f, path, frame)
        obj = int(f["object"][frame])
        if not obj:
            return ""
        name = json.loads(f.attrs["object_names"])[obj]  # 0: none
        return _label_line(name, f["object_box"][frame], sensor, sensor_poses(f, sensor, frame))


def kitti_poses(path: str | Path) -> str:
    """KITTI odometry's ``poses.txt`` of a sweep in motion: one line a frame, in the file's
    order, the 12 numbers of the 3 x 4 ``[R | t]`` row by row (``%e``, as KITTI writes them):
    the pose of the frame's sensor at its reference time in the sensor's frame at the
    reference time of the first frame of its sequence (sequences restart at the identity),
    both in camera axes, as KITTI's are camera poses: ``C T0^-1 Tk C^-1`` with ``C``
    :data:`VELO_TO_CAM` and ``T`` the sensor's poses (:func:`sensor_poses`). A sweep that does
    not move has none: ""."""
    import h5py

    with h5py.File(path, "r") as f:
        sensor = check_frame(f, path, 0)
        poses = sensor_poses(f, sensor, slice(None))
        if poses is None:
            return ""
        length = sequence_frames(f, path)
    first = np.arange(len(poses.rotation)) // length * length
    seen = poses.relative_to(Poses(poses.rotation[first], poses.translation_m[first]))
    rotation = VELO_TO_CAM @ seen.rotation @ VELO_TO_CAM.T
    translation = seen.translation_m @ VELO_TO_CAM.T
    rows = np.concatenate([rotation, translation[..., None]], axis=-1).reshape(-1, 12) + 0.0
    return "".join(" ".join(f"{v:e}" for v in row) + "\n" for row in rows)  # + 0.0: no -0


def kitti_tracking(path: str | Path, sequence: int) -> str:
    """KITTI tracking's label file (``label_02/SSSS.txt``) of sequence ``sequence`` of a sweep
    in motion: one line a frame that has its object, ``frame track_id`` and the 15 columns of
    :func:`kitti_label` (its box at the frame's reference time, in that frame's camera
    coordinates): frame counted within the sequence, track 0 (one object a scene). ""
    for a sequence without object."""
    import h5py

    with h5py.File(path, "r") as f:
        sensor = check_frame(f, path, 0)
        length, count = sequence_frames(f, path), f["labels"].shape[0]
        names = json.loads(f.attrs["object_names"])
        first, lines = sequence * length, []
        for step, frame in enumerate(range(first, min(first + length, count))):
            obj = int(f["object"][frame])
            if obj:
                box, pose = f["object_box"][frame], sensor_poses(f, sensor, frame)
                lines.append(f"{step} 0 " + _label_line(names[obj], box, sensor, pose))
    return "".join(lines)


def instance_ids(path: str | Path, frame: int, surface: np.ndarray) -> np.ndarray | None:
    """Each point's instance id (SemanticKITTI's upper 16 bits) in frame ``frame`` of a sweep
    in motion, from its ``surface`` (P,): :data:`OBJECT_INSTANCE` on the frame's labelled
    object, the points whose surface bears an object's name (the file's ``object_names``
    among its ``surface_names``: car, pedestrian, truck in the shipped catalog), 0 elsewhere
    and in a frame without object. (P,) uint32; None for a sweep that does not move (its
    labels keep the bytes they had before instance ids)."""
    import h5py

    with h5py.File(path, "r") as f:
        check_frame(f, path, frame)
        if "ego_pose" not in f:
            return None
        obj = int(f["object"][frame])
        surfaces = json.loads(f.attrs["surface_names"])
        names = set(json.loads(f.attrs["object_names"])[1:])  # 0: none
    on_object = np.isin(surface, [k for k, name in enumerate(surfaces) if name in names])
    return np.where(on_object & (obj != 0), OBJECT_INSTANCE, 0).astype("<u4")


def kitti_file(path: str | Path, frame: int, folder: str, points=None) -> bytes:
    """The bytes of one file of frame ``frame`` in the KITTI export (:func:`export_frame`):
    ``folder`` ``velodyne`` (float32 x, y, z, intensity), ``labels`` (uint32 surface a point,
    in motion with its instance id, :func:`instance_ids`, in the upper 16 bits), ``label_2``
    (:func:`kitti_label`) or ``calib`` (:data:`KITTI_CALIB`). ``points``: the frame's
    :func:`frame_points`, if already made."""
    if folder == "label_2":
        return kitti_label(path, frame).encode()
    if folder == "calib":
        return KITTI_CALIB.encode()
    points = frame_points(path, frame) if points is None else points
    if folder == "velodyne":
        # SCAN_COLUMNS: x, y, z and, as reflectance, the intensity proxy; in motion deskewed
        # to the frame's reference time, as KITTI ships its scans
        xyz = deskewed_xyz(path, frame, points)
        xyzi = np.concatenate([xyz, points["intensity"][:, None]], axis=1)
        return xyzi.astype(SCAN_DTYPE).tobytes()
    if folder == "labels":
        labels = points["surface"].astype("<u4")
        instances = instance_ids(path, frame, points["surface"])
        if instances is not None:
            labels |= instances << INSTANCE_SHIFT
        return labels.tobytes()
    raise ConfigError(f"KITTI folder {folder!r}: expected velodyne, labels, label_2 or calib")


def sequence_files(path: str | Path, frame: int) -> dict[str, bytes]:
    """The KITTI files of a sweep in motion that frame ``frame`` completes, by their path in
    the export: the tracking labels of its sequence (:func:`kitti_tracking`) where it is the
    sequence's last frame, and :func:`kitti_poses` where it is the sweep's last. They are
    made from the sweep file alone, so exporting every frame, in any order, writes each once.
    Nothing for a sweep that does not move."""
    import h5py

    with h5py.File(path, "r") as f:
        check_frame(f, path, frame)
        if "ego_pose" not in f:
            return {}
        length, count = sequence_frames(f, path), f["labels"].shape[0]
    files = {}
    if (frame + 1) % length == 0 or frame == count - 1:  # its sequence's last
        sequence = frame // length
        files[f"{TRACKING_FOLDER}/{sequence:04d}.txt"] = kitti_tracking(path, sequence).encode()
    if frame == count - 1:
        files[POSES_FILE] = kitti_poses(path).encode()
    return files


_PLY_TYPES = {"<f4": "float", "u1": "uchar", "<f8": "double", "<u2": "ushort"}
_PCD_TYPES = {"<f4": ("4", "F"), "u1": ("1", "U"), "<f8": ("8", "F"), "<u2": ("2", "U")}


def with_motion_fields(path: str | Path, frame: int, points: np.ndarray) -> np.ndarray:
    """A frame's ``points`` with, in a sweep in motion, :data:`MOTION_POINT_FIELDS`: each
    point deskewed to the frame's reference pose (:func:`deskewed_xyz`) and its instance id
    (:func:`instance_ids`); the points as they are for a sweep that does not move."""
    instances = instance_ids(path, frame, points["surface"])
    if instances is None:
        return points
    more = np.empty(len(points), np.dtype(points.dtype.descr + MOTION_POINT_FIELDS))
    for name in points.dtype.names:
        more[name] = points[name]
    xyz = deskewed_xyz(path, frame, points)
    for k, name in enumerate(("x_deskewed", "y_deskewed", "z_deskewed")):
        more[name] = xyz[:, k]
    more["instance"] = instances
    return more


def export_frame(path: str | Path, frame: int, out: str | Path, fmt: str) -> list[Path]:
    """Write frame ``frame`` of a sweep file under ``out`` as ``fmt``: ``kitti``
    (``velodyne/NNNNNN.bin``: float32 x, y, z, intensity, KITTI's layout;
    ``labels/NNNNNN.label``: uint32 surface index a point, SemanticKITTI's; and the object
    benchmark's ``label_2/NNNNNN.txt`` and ``calib/NNNNNN.txt``, :func:`kitti_label`, so that
    ``simlidar convert kitti`` reads the folder; in motion the instance ids in the labels and
    the files the frame completes, :func:`sequence_files`), ``ply``
    (``ply/NNNNNN.ply``, binary little endian, every field of :data:`POINT_DTYPE`, or of
    :data:`RETURN_POINT_DTYPE` for a sweep that stores every reported return: one point a
    return, with its return number; in motion also :data:`MOTION_POINT_FIELDS`,
    :func:`with_motion_fields`) or ``pcd`` (``pcd/NNNNNN.pcd``, PCD 0.7 binary, the same
    fields). Returns the files written."""
    points = frame_points(path, frame)
    out, stem = Path(out), f"{frame:06d}"
    if fmt == "kitti":
        folders = {"velodyne": ".bin", "labels": ".label", "label_2": ".txt", "calib": ".txt"}
        files = [out / folder / f"{stem}{suffix}" for folder, suffix in folders.items()]
        blobs = [kitti_file(path, frame, folder, points) for folder in folders]
        for name, blob in sequence_files(path, frame).items():
            files.append(out / name)
            blobs.append(blob)
    elif fmt == "ply":
        points = with_motion_fields(path, frame, points)
        header = ["ply", "format binary_little_endian 1.0", f"element vertex {len(points)}"]
        header += [
            f"property {_PLY_TYPES[points.dtype[k].str.lstrip('|')]} {k}"
            for k in points.dtype.names
        ]
        files = [out / "ply" / f"{stem}.ply"]
        blobs = ["\n".join([*header, "end_header"]).encode() + b"\n" + points.tobytes()]
    elif fmt == "pcd":
        points = with_motion_fields(path, frame, points)
        kinds = [_PCD_TYPES[points.dtype[k].str.lstrip("|")] for k in points.dtype.names]
        header = [
            "# .PCD v0.7 - Point Cloud Data file format",
            "VERSION 0.7",
            "FIELDS " + " ".join(points.dtype.names),
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
