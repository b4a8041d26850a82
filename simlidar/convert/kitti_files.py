"""Reading the KITTI 3D object benchmark's training layout: labels, calibration, scans.

    ROOT/[training/]label_2/NNNNNN.txt   one object per line, 15 columns (camera frame)
    ROOT/[training/]calib/NNNNNN.txt     'KEY: numbers' lines; R0_rect and Tr_velo_to_cam used
    ROOT/[training/]velodyne/NNNNNN.bin  float32 x, y, z, reflectance per point (Velodyne frame)

The scans' and label lines' layouts are :mod:`simlidar.dataset.kitti`'s, which a sweep's KITTI
export writes by.

Every malformed input raises a DatasetError naming the file, the line and what was expected.
The files are read through a :class:`TrainingFiles` (a folder on disk), or through its
subclass for a simlidar sweep without the KITTI export (:mod:`simlidar.convert.kitti`), which
makes the same bytes from the sweep's ``frames.h5``.
"""

import hashlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from simlidar.dataset.kitti import LABEL_COLUMNS, SCAN_COLUMNS, SCAN_DTYPE
from simlidar.errors import DatasetError

CLASSES = ("Car", "Van", "Truck", "Pedestrian", "Person_sitting", "Cyclist", "Tram", "Misc")
SKIPPED = ("DontCare",)
_CALIB_SIZES = {"R0_rect": 9, "Tr_velo_to_cam": 12}
# A box's sizes and bottom centre, metres: 10 km is 10 times the farthest delay-1 range the
# converter takes (1 km). Beyond it a label means nothing, and 1e308 overflowed the corners'
# arithmetic and the float32 columns (numpy warnings, inf written).
BOX_LIMIT_M = 10_000.0


@dataclass(frozen=True)
class Label:
    """One labelled object of a frame."""

    kind: str  # one of CLASSES
    truncated: float  # 0 (fully visible) .. 1 (leaving the image)
    occluded: int  # 0 visible, 1 partly, 2 largely occluded, 3 unknown
    box: tuple[float, ...]  # h_m, w_m, l_m, x_m, y_m, z_m (bottom centre), rotation_y_rad
    line: int  # 1-based line in the label file


@dataclass(frozen=True)
class Frame:
    """One frame of the benchmark: its files, labelled objects and camera -> Velodyne matrix."""

    number: int  # the file name's digits: 000001 -> 1
    velodyne: Path
    labels: tuple[Label, ...]
    cam_to_velo: np.ndarray  # (4, 4): inverse of Tr_velo_to_cam (4 x 4) times inverse of R0_rect


class TrainingFiles:
    """The files of a KITTI training folder, by path relative to it (``label_2/000001.txt``):
    what the converter reads and hashes."""

    def __init__(self, base: Path):
        self.base = base

    def stems(self) -> list[str]:
        """Every label file's name without ``.txt``, in name order."""
        return sorted(p.stem for p in (self.base / "label_2").glob("*.txt"))

    def has(self, relative: Path) -> bool:
        return (self.base / relative).is_file()

    def read(self, relative: Path) -> bytes:
        return (self.base / relative).read_bytes()


def training_dir(root: str | Path) -> Path:
    """The folder holding label_2/, calib/ and velodyne/: ``root`` or ``root/training``."""
    root = Path(root)
    for candidate in (root, root / "training"):
        if all((candidate / d).is_dir() for d in ("label_2", "calib", "velodyne")):
            return candidate
    raise DatasetError(
        f"{root}: expected the KITTI object benchmark's training layout (label_2/, calib/ and "
        "velodyne/ here or under training/)"
    )


def _number(path: Path, line: int, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise DatasetError(f"{path} line {line}: {text!r} is not a number") from None
    if not np.isfinite(value):
        raise DatasetError(f"{path} line {line}: {text!r}: expected a finite number")
    return value


def _text(path: Path, data: bytes) -> str:
    try:
        return data.decode()
    except UnicodeDecodeError as exc:
        raise DatasetError(f"{path}: byte {exc.start}: expected UTF-8 text") from None


def read_labels(path: Path, data: bytes) -> tuple[Label, ...]:
    """The objects of one label file (``data``, its bytes; ``path`` names it), DontCare
    skipped."""
    labels = []
    for line, text in enumerate(_text(path, data).splitlines(), 1):
        fields = text.split()
        if not fields:
            continue
        if len(fields) not in (15, 16):  # 16: a detection score after the 15 label columns
            raise DatasetError(
                f"{path} line {line}: {len(fields)} columns, expected {len(LABEL_COLUMNS)} "
                f"({' '.join(LABEL_COLUMNS)})"
            )
        kind = fields[0]
        if kind in SKIPPED:
            continue
        if kind not in CLASSES:
            raise DatasetError(
                f"{path} line {line}: type {kind!r}, expected one of {', '.join(CLASSES + SKIPPED)}"
            )
        values = [_number(path, line, f) for f in fields[1:15]]
        truncated, occluded, box = values[0], values[1], tuple(values[7:14])
        if occluded not in (0, 1, 2, 3):
            raise DatasetError(f"{path} line {line}: occluded {fields[2]!r}, expected 0..3")
        if not 0.0 <= truncated <= 1.0:
            raise DatasetError(
                f"{path} line {line}: truncated {fields[1]!r}, expected 0..1 (0: in the image)"
            )
        if min(box[:3]) <= 0 or max(box[:3]) > BOX_LIMIT_M:
            raise DatasetError(
                f"{path} line {line}: box size h w l = {' '.join(fields[8:11])}, expected "
                f"positive metres up to {BOX_LIMIT_M:g}"
            )
        if max(abs(v) for v in box[3:6]) > BOX_LIMIT_M:
            raise DatasetError(
                f"{path} line {line}: box location x y z = {' '.join(fields[11:14])}, expected "
                f"metres within +-{BOX_LIMIT_M:g}"
            )
        labels.append(Label(kind, truncated, int(occluded), box, line))
    return tuple(labels)


def read_cam_to_velo(path: Path, data: bytes) -> np.ndarray:
    """(4, 4) matrix taking rectified camera coordinates to Velodyne coordinates: the inverse of
    ``R0_rect``, then the inverse of ``Tr_velo_to_cam`` (both made 4 x 4), from a calibration
    file's bytes ``data`` (``path`` names it)."""
    found: dict[str, np.ndarray] = {}
    for line, text in enumerate(_text(path, data).splitlines(), 1):
        if not text.strip():
            continue
        key, sep, rest = text.partition(":")
        if not sep or not key.strip() or " " in key.strip():
            raise DatasetError(f"{path} line {line}: {text[:40]!r}, expected 'KEY: numbers'")
        numbers = [_number(path, line, t) for t in rest.split()]
        key = key.strip()
        if key in _CALIB_SIZES:
            if len(numbers) != _CALIB_SIZES[key]:
                raise DatasetError(
                    f"{path} line {line}: {key} has {len(numbers)} numbers, expected "
                    f"{_CALIB_SIZES[key]} (row-major)"
                )
            found[key] = np.array(numbers)
    for key, size in _CALIB_SIZES.items():
        if key not in found:
            raise DatasetError(f"{path}: no {key} line (expected '{key}: {size} numbers')")
    r0 = np.eye(4)
    r0[:3, :3] = found["R0_rect"].reshape(3, 3)
    tr = np.eye(4)
    tr[:3, :] = found["Tr_velo_to_cam"].reshape(3, 4)
    try:
        return np.linalg.inv(tr) @ np.linalg.inv(r0)
    except np.linalg.LinAlgError:
        raise DatasetError(f"{path}: R0_rect or Tr_velo_to_cam is singular") from None


def read_velodyne(path: Path, data: bytes) -> tuple[np.ndarray, str]:
    """One scan from its file's bytes ``data`` (``path`` names it): ((n, 3) float64 x, y, z in
    metres, sha256 of the file)."""
    size = len(SCAN_COLUMNS) * SCAN_DTYPE.itemsize  # 16 bytes a point
    if len(data) % size:
        raise DatasetError(
            f"{path}: {len(data)} bytes, expected a multiple of {size} "
            f"(float32 {', '.join(SCAN_COLUMNS)})"
        )
    columns = np.frombuffer(data, dtype=SCAN_DTYPE).reshape(-1, len(SCAN_COLUMNS))
    points = columns[:, :3].astype(np.float64)
    if not np.isfinite(points).all():
        raise DatasetError(f"{path}: non-finite coordinates, expected finite metres")
    return points, hashlib.sha256(data).hexdigest()


def read_frames(files: TrainingFiles) -> list[Frame]:
    """Every frame with a label file, in file-name order, labels and calibration read and
    checked; the scans are read later, one at a time."""
    base = files.base
    frames = []
    for stem in files.stems():
        label_file = base / "label_2" / f"{stem}.txt"
        if not stem.isdigit():
            raise DatasetError(f"{label_file}: expected a file name of digits (000001.txt)")
        calib, velodyne = Path("calib", f"{stem}.txt"), Path("velodyne", f"{stem}.bin")
        for needed in (calib, velodyne):
            if not files.has(needed):
                raise DatasetError(f"{base / needed}: missing (the frame of {label_file})")
        labels = read_labels(label_file, files.read(label_file.relative_to(base)))
        matrix = read_cam_to_velo(base / calib, files.read(calib))
        frames.append(Frame(int(stem), base / velodyne, labels, matrix))
    if not frames:
        raise DatasetError(f"{base / 'label_2'}: no label files (expected NNNNNN.txt)")
    return frames


def box_corners_cam(box: tuple[float, ...]) -> np.ndarray:
    """The 8 corners (8, 3) of a KITTI box in camera coordinates (x right, y down, z forward).

    Bottom face 0-3, then the top face 4-7 above them, as the KITTI devkit orders them:
    corner 0 is at +l/2 (length axis), +w/2 (width axis) of the bottom centre; 1 at -w/2;
    3 at -l/2; 4 above 0. The box turns by rotation_y about the camera's y axis.
    """
    h, w, length, x, y, z, ry = box
    along = np.array([1, 1, -1, -1, 1, 1, -1, -1]) * length / 2
    up = np.array([0, 0, 0, 0, -1, -1, -1, -1]) * h
    across = np.array([1, -1, -1, 1, 1, -1, -1, 1]) * w / 2
    c, s = np.cos(ry), np.sin(ry)
    return np.stack([c * along + s * across + x, up + y, -s * along + c * across + z], axis=1)


def to_velo(points_cam: np.ndarray, cam_to_velo: np.ndarray) -> np.ndarray:
    """(n, 3) camera coordinates -> (n, 3) Velodyne coordinates."""
    homogeneous = np.concatenate([points_cam, np.ones((len(points_cam), 1))], axis=1)
    return (homogeneous @ cam_to_velo.T)[:, :3]


def inside_box(points: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """(n,) bool: which points (n, 3) lie inside the box given by its corners (8, 3) in the
    same frame (the box's edges from corner 0 to corners 3, 1 and 4)."""
    offset = points - corners[0]
    inside = np.ones(len(points), dtype=bool)
    for k in (3, 1, 4):
        edge = corners[k] - corners[0]
        along = offset @ edge
        inside &= (along >= 0) & (along <= edge @ edge)
    return inside
