"""A sweep's frames as point-cloud files (``simlidar sweep --export``): KITTI ``.bin`` with a
SemanticKITTI-style ``.label`` of surfaces and the object benchmark's label and calibration
files (so that ``simlidar convert kitti`` reads the folder), PLY or PCD. The file formats:
docs/sweeps.md.
"""

import json
from pathlib import Path

import numpy as np

from simlidar.dataset.kitti import LABEL_COLUMNS, SCAN_DTYPE
from simlidar.errors import ConfigError
from simlidar.generator.frames import check_frame, deskewed_xyz, frame_points

EXPORTS = ("kitti", "ply", "pcd")

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
        sensor = check_frame(f, path, frame)
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
    given = {"alpha": alpha, "h": height, "w": width, "l": length, "x": cx, "y": cy, "z": cz}
    given["rotation_y"] = ry
    numbers = [given.get(column, 0) for column in LABEL_COLUMNS[1:]]  # the others: 0
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
        # SCAN_COLUMNS: x, y, z and, as reflectance, the intensity proxy; in motion deskewed
        # to the frame's reference time, as KITTI ships its scans
        xyz = deskewed_xyz(path, frame, points)
        xyzi = np.concatenate([xyz, points["intensity"][:, None]], axis=1)
        return xyzi.astype(SCAN_DTYPE).tobytes()
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
    (``ply/NNNNNN.ply``, binary little endian, every field of :data:`POINT_DTYPE`, or of
    :data:`RETURN_POINT_DTYPE` for a sweep that stores every reported return: one point a
    return, with its return number) or ``pcd`` (``pcd/NNNNNN.pcd``, PCD 0.7 binary, the same
    fields). Returns the files written."""
    points = frame_points(path, frame)
    out, stem = Path(out), f"{frame:06d}"
    if fmt == "kitti":
        folders = {"velodyne": ".bin", "labels": ".label", "label_2": ".txt", "calib": ".txt"}
        files = [out / folder / f"{stem}{suffix}" for folder, suffix in folders.items()]
        blobs = [kitti_file(path, frame, folder, points) for folder in folders]
    elif fmt == "ply":
        header = ["ply", "format binary_little_endian 1.0", f"element vertex {len(points)}"]
        header += [
            f"property {_PLY_TYPES[points.dtype[k].str.lstrip('|')]} {k}"
            for k in points.dtype.names
        ]
        files = [out / "ply" / f"{stem}.ply"]
        blobs = ["\n".join([*header, "end_header"]).encode() + b"\n" + points.tobytes()]
    elif fmt == "pcd":
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
