"""KITTI 3D object benchmark -> front-view pulse crops in the simlidar schema.

Each scan is projected into the expanded front view (Wang et al. 2020, after Chen et al.'s
MV3D), with the Velodyne frame's x forward, y left, z up:

    x_front = floor(atan2(-y, x) * 180 / (pi * res_h))      column, left to right
    y_front = floor(-atan2(z, d) * 180 / (pi * res_v))      row, top to bottom
    d = sqrt(x^2 + y^2)

A cell keeps its nearest point, whose range r = sqrt(x^2 + y^2 + z^2) gives the round-trip time
of flight 2 r / c; the delay is that over the time of flight at ``max_range_m`` (100 m, as the
generator's VLP-16), and 1.0 where the cell is empty or the point is that far or farther.
``docs/converters.md`` has the details; :func:`convert_kitti` is the entry point.
"""

import hashlib
import json
from pathlib import Path

import numpy as np

from simlidar.atomic import building
from simlidar.convert.common import (
    choose_test,
    delays_from_times,
    stream,
)
from simlidar.convert.config import KittiConfig
from simlidar.convert.kitti_files import (
    CLASSES,
    Frame,
    TrainingFiles,
    box_corners_cam,
    inside_box,
    read_frames,
    read_velodyne,
    to_velo,
    training_dir,
)
from simlidar.dataset.schema import (
    CONVERTED_SCHEMAS,
    SPLITS,
    SWEEP_FILE,
    SWEEP_FORMAT,
    expected_shapes,
)
from simlidar.dataset.storage import check_storage
from simlidar.dataset.version import SOURCES
from simlidar.dataset.writer import SplitWriter, attrs_fit
from simlidar.errors import DatasetError
from simlidar.generator.declared_card import converted_split_attrs, write_release_files
from simlidar.sensor.model import tof_ns

SOURCE = "kitti"


def front_view(points: np.ndarray, res_h_deg: float, res_v_deg: float):
    """The front-view cell of every point.

    points : (n, 3) float x, y, z in the Velodyne frame, metres
    returns : rows y_front (n,) int64, columns x_front (n,) int64
    """
    x, y, z = points[:, 0], points[:, 1], points[:, 2]
    d = np.sqrt(x**2 + y**2)
    cols = np.floor(np.arctan2(-y, x) * 180 / (np.pi * res_h_deg)).astype(np.int64)
    rows = np.floor(-np.arctan2(z, d) * 180 / (np.pi * res_v_deg)).astype(np.int64)
    return rows, cols


def crop_ranges(
    rows: np.ndarray,
    cols: np.ndarray,
    range_m: np.ndarray,
    origin: tuple[int, int],
    shape: tuple[int, int],
    columns: int,
) -> np.ndarray:
    """The nearest range in every cell of one crop.

    rows, cols, range_m : (n,) the points' cells and ranges
    origin : front-view (row, column) of the crop's top-left cell; columns wrap modulo
        ``columns`` (the 360 degree view closes on itself)
    shape : the crop's (rows H, columns W)
    returns : (H, W) float64 metres, NaN where no point fell
    """
    height, width = shape
    i = rows - origin[0]
    j = (cols - origin[1]) % columns
    inside = (i >= 0) & (i < height) & (j < width)
    nearest = np.full(height * width, np.inf)
    np.minimum.at(nearest, i[inside] * width + j[inside], range_m[inside])
    nearest[np.isinf(nearest)] = np.nan
    return nearest.reshape(height, width)


def crop_origin(centre: np.ndarray, config: KittiConfig) -> tuple[int, int]:
    """Top-left front-view cell (row, column) of the crop centred on ``centre`` (3,), the
    column brought into [-columns / 2, columns / 2)."""
    row, col = (int(v[0]) for v in front_view(centre[None], config.res_h_deg, config.res_v_deg))
    half = config.columns // 2
    return row - config.crop[0] // 2, (col - config.crop[1] // 2 + half) % config.columns - half


def frame_crops(frame: Frame, points: np.ndarray, config: KittiConfig) -> dict[str, np.ndarray]:
    """Every labelled object of one frame as a crop, with its records (the KITTI schema).

    points : (n, 3) the frame's scan, Velodyne frame, metres
    returns : name -> (objects, ...) array, one row per label in file order
    """
    rows, cols = front_view(points, config.res_h_deg, config.res_v_deg)
    range_m = np.sqrt((points**2).sum(axis=1))
    tof_max = tof_ns(config.max_range_m)
    out: dict[str, list] = {name: [] for name in CONVERTED_SCHEMAS[SOURCE]}
    for label in frame.labels:
        corners = to_velo(box_corners_cam(label.box), frame.cam_to_velo)  # (8, 3)
        origin = crop_origin(corners.mean(axis=0), config)
        nearest = crop_ranges(rows, cols, range_m, origin, config.crop, config.columns)
        out["delays"].append(delays_from_times(tof_ns(nearest), tof_max))
        out["labels"].append(CLASSES.index(label.kind))
        out["frame"].append(frame.number)
        out["crop_origin"].append(origin)
        out["box_corners_m"].append(corners)
        out["box_points"].append(int(inside_box(points, corners).sum()))
        out["truncated"].append(label.truncated)
        out["occluded"].append(label.occluded)
    shapes = expected_shapes(SOURCE, len(frame.labels), *config.crop)
    return {
        name: np.array(out[name], dtype=d).reshape(shape) for name, (d, shape) in shapes.items()
    }


def split_frames(frames: list[Frame], config: KittiConfig) -> dict[str, list[Frame]]:
    """Train and test frames: a seeded choice among the frames with labelled objects (frames
    without any join neither split). DatasetError with fewer than two such frames."""
    useful = [f for f in frames if f.labels]
    if len(useful) < 2:
        raise DatasetError(
            f"{len(useful)} frame(s) with labelled objects: expected at least 2, so that train "
            "and test get different frames"
        )
    test = choose_test(len(useful), config.test_fraction, stream(config.seed))
    return {
        "train": [f for f, t in zip(useful, test) if not t],
        "test": [f for f, t in zip(useful, test) if t],
    }


def kitti_name(config: KittiConfig, simulated: dict | None = None) -> str:
    """``kitti-front-<H>x<W>[-sim]-v<version>``; ``-sim``: the frames are a simlidar sweep's."""
    sim = "-sim" if simulated else ""
    return f"kitti-front-{config.crop[0]}x{config.crop[1]}{sim}-v{SOURCES[SOURCE][0]}"


class SweepFiles(TrainingFiles):
    """A simlidar sweep's folder read as a KITTI training folder without its ``--export kitti``
    files: each file's bytes are made from ``frames.h5`` as the export would write them
    (:func:`simlidar.generator.exports.kitti_file`), so the crops and every hash are those of
    the exported folder, without its 1.6 MB of scan a frame on disk."""

    FOLDERS = ("label_2", "calib", "velodyne")

    def __init__(self, base: Path):
        import h5py

        super().__init__(base)
        path = base / SWEEP_FILE
        with h5py.File(path, "r") as f:
            # a sweep from elsewhere: every dataset stored in the file as the sweep writes it
            # (no external file, virtual dataset, unknown filter or huge chunk) before any read
            problems = check_storage(path, f)
            if problems:
                more = f" (and {len(problems) - 1} more)" * (len(problems) > 1)
                raise DatasetError(problems[0] + more)
            self.frames = f["labels"].shape[0]

    def stems(self) -> list[str]:
        return [f"{frame:06d}" for frame in range(self.frames)]

    def has(self, relative: Path) -> bool:
        stem = relative.stem
        return relative.parent.name in self.FOLDERS and stem.isdigit() and int(stem) < self.frames

    def read(self, relative: Path) -> bytes:
        from simlidar.generator.exports import kitti_file

        return kitti_file(self.base / SWEEP_FILE, int(relative.stem), relative.parent.name)


def training_files(root: str | Path) -> TrainingFiles:
    """The KITTI training folder at ``root`` (or ``root/training``); or a simlidar sweep's
    folder without its KITTI export, read from its ``frames.h5`` (:class:`SweepFiles`)."""
    root = Path(root)
    if simulated_from(root) and not (root / "velodyne").is_dir():
        return SweepFiles(root)
    return TrainingFiles(training_dir(root))


def simulated_from(base: Path) -> dict | None:
    """Where the frames of the training folder ``base`` came from, when it is a simlidar sweep
    (its ``frames.h5`` beside the KITTI folders, or alone): the sweep's name and sensor model;
    None for recorded data."""
    import h5py

    sweep = base / SWEEP_FILE
    if not sweep.is_file():
        return None
    try:
        with h5py.File(sweep, "r") as f:
            if f.attrs.get("format") != SWEEP_FORMAT:
                return None
            model = json.loads(f.attrs["sensor"]).get("model", "Velodyne VLP-16")
    except OSError:
        return None
    return {"sweep": base.name, "sensor_model": model}


def convert_kitti(
    root: str | Path,
    out: str | Path,
    *,
    force: bool = False,
    progress: bool = True,
    preview: bool = True,
    **options,
) -> Path:
    """Convert the KITTI 3D object benchmark's training frames (ROOT: the folder with label_2/,
    calib/ and velodyne/, or its parent) into front-view pulse crops, one per labelled object
    (8 classes, DontCare skipped), written to OUT/kitti-front-<H>x<W>-v<version>/.

    Every scan is projected into the expanded front view (res_h_deg x res_v_deg cells); a cell's
    nearest point becomes a pulse delay, its time of flight over that at max_range_m (1.0 = no
    return). Crops of crop = (rows, columns) cells are centred on each 3D box. Frames are split
    between train and test (test_fraction of them, seeded; at least one each, so at least two
    frames with objects are needed). Returns the dataset directory.

    root : the KITTI folder (training/, or the folder holding label_2/, calib/ and velodyne/)
    out : the folder that receives the dataset directory (made if missing)
    force : replace a dataset directory of the same name (else an error names it)
    progress : a progress bar on stderr
    preview : draw the dataset's ``preview.png``
    options : the fields of :class:`~simlidar.convert.config.KittiConfig` (crop, res_h_deg,
        res_v_deg, max_range_m, test_fraction, seed), each with its default there
    """
    config = KittiConfig(**options)
    files = training_files(root)
    frames = read_frames(files)
    splits = split_frames(frames, config)
    simulated = simulated_from(files.base)
    name = kitti_name(config, simulated)
    with building(out, name, force) as temp:
        write_splits(temp, files, frames, splits, config, progress, simulated)
        write_release_files(temp, name, preview)
    return Path(out) / name


def write_splits(
    folder: Path,
    files: TrainingFiles,
    frames: list[Frame],
    splits: dict[str, list[Frame]],
    config: KittiConfig,
    progress: bool = True,
    simulated: dict | None = None,
) -> None:
    """Read every scan once, in split order, and write train.h5 and test.h5 into ``folder``.

    files : the training folder's files (paths in the input's hash are relative to it)
    frames : every frame with a label file (:func:`~simlidar.convert.kitti_files.read_frames`):
        the scans of those without objects count in the input's hash, and their numbers are
        stored (``frames_without_objects``)
    splits : the train and test frames (:func:`split_frames`)
    config : the crops and their delays (:class:`~simlidar.convert.config.KittiConfig`)
    progress : a progress bar on stderr
    simulated : :func:`simulated_from` of ``base``, stored as the attribute ``simulated_from``
    """
    from tqdm import tqdm

    shapes = {n: (d, s[1:]) for n, (d, s) in expected_shapes(SOURCE, 0, *config.crop).items()}
    writers: dict[str, SplitWriter] = {}
    try:
        base = files.base
        hashes = _small_file_hashes(files, frames)
        # one int64 a frame: beyond 8,182 frames (a sweep of ~30,000) the HDF5 1.8 format
        without = np.array([f.number for f in frames if not f.labels], dtype=np.int64)
        large = not attrs_fit({"frames_without_objects": without})
        for split in SPLITS:
            size = sum(len(f.labels) for f in splits[split])
            writers[split] = SplitWriter(
                folder / f"{split}.h5",
                size,
                shapes,
                {},
                frozenset({"delays", "box_corners_m"}),
                large_attrs=large,
            )
        bar = tqdm(total=len(frames), unit="frame", disable=not progress, desc="kitti")
        for split in SPLITS:
            for frame in splits[split]:
                scan = frame.velodyne.relative_to(base)
                points, hashes[scan] = read_velodyne(frame.velodyne, files.read(scan))
                writers[split].append(frame_crops(frame, points, config))
                bar.update()
        for frame in frames:  # frames without objects count in the input's hash too
            scan = frame.velodyne.relative_to(base)
            if scan not in hashes:
                hashes[scan] = hashlib.sha256(files.read(scan)).hexdigest()
                bar.update()
        bar.close()
        # the text `sha256sum calib/* label_2/* velodyne/*` prints in the training folder
        manifest = "".join(f"{h}  {p.as_posix()}\n" for p, h in sorted(hashes.items()))
        recorded = "Velodyne HDL-64E (KITTI, 10 Hz)"
        sensor = {
            "name": f"{simulated['sensor_model']} (simulated: simlidar sweep)"
            if simulated
            else recorded,
            "res_h_deg": config.res_h_deg,
            "res_v_deg": config.res_v_deg,
            "max_range_m": config.max_range_m,
        }
        for split, writer in writers.items():
            attrs = converted_split_attrs(
                SOURCE,
                split,
                config,
                CLASSES,
                "object",
                sensor,
                hashlib.sha256(manifest.encode()).hexdigest(),
            )
            attrs["tof_max_ns"] = tof_ns(config.max_range_m)
            if simulated:
                attrs["simulated_from"] = json.dumps(simulated, sort_keys=True)
            attrs["frames_without_objects"] = without
            for key, value in attrs.items():
                writer.file.attrs[key] = value
            writer.close()
    finally:
        for writer in writers.values():
            writer.abort()  # a no-op after close()


def _small_file_hashes(files: TrainingFiles, frames: list[Frame]) -> dict[Path, str]:
    """sha256 of every frame's label and calibration file, by path relative to the folder."""
    hashes = {}
    for frame in frames:
        for folder in ("label_2", "calib"):
            path = Path(folder, f"{frame.velodyne.stem}.txt")
            hashes[path] = hashlib.sha256(files.read(path)).hexdigest()
    return hashes
