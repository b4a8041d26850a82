"""Fixtures of the converter tests: KITTI training folders (one built here from a simulated
sweep, in every clone; the real sample, read in place and never copied, where it is), their
converted datasets, and small synthetic inputs the tests write themselves."""

import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from simlidar.convert import convert_kitti

ROOT = Path(__file__).resolve().parents[2]
KITTI_SAMPLE = Path(
    os.environ.get("SIMLIDAR_KITTI_SAMPLE", ROOT / ".." / "shared" / "data" / "kitti-sample")
)

# A calibration whose camera axes are the Velodyne's renamed, as KITTI's nearly are:
# camera x = -velodyne y (right), camera y = -velodyne z (down), camera z = velodyne x (ahead).
SIMPLE_CALIB = """P0: 1 0 0 0 0 1 0 0 0 0 1 0
R0_rect: 1 0 0 0 1 0 0 0 1
Tr_velo_to_cam: 0 -1 0 0 0 0 -1 0 1 0 0 0
"""


@pytest.fixture(scope="session")
def kitti_sample() -> Path:
    """The three real frames of ../shared/data/kitti-sample (or $SIMLIDAR_KITTI_SAMPLE)."""
    if not (KITTI_SAMPLE / "training" / "velodyne").is_dir():
        pytest.skip(
            f"KITTI sample not found at {KITTI_SAMPLE}: set SIMLIDAR_KITTI_SAMPLE to the folder "
            "holding training/ (three frames of the 3D object benchmark)"
        )
    return KITTI_SAMPLE


# A DontCare line as KITTI writes them (the real sample's frame 000001 has two): skipped.
DONT_CARE = "DontCare -1 -1 -10 503.89 169.71 590.61 190.13 -1 -1 -1 -1000 -1000 -1000 -10\n"


@pytest.fixture(scope="session")
def built_kitti(tmp_path_factory) -> Path:
    """A KITTI training folder made here, so that the format checks run in any clone: 8 frames
    of an HDL-64E sweep exported in KITTI's layout (`simlidar sweep --export kitti`: label_2/,
    calib/, velodyne/; 6 frames with a car, pedestrian or truck, 2 without), moved under
    ``training/`` without the sweep's frames.h5, so that the converter reads them as recorded
    frames, plus a DontCare line in frame 000002."""
    from click.testing import CliRunner

    from simlidar.cli import main

    out = tmp_path_factory.mktemp("built-kitti")
    args = ["sweep", "--frames", "8", "--sensor", "hdl64e", "--export", "kitti"]
    done = CliRunner().invoke(main, [*args, "--out", str(out / "sweep"), "--json"])
    assert done.exit_code == 0, done.output
    sweep = Path(json.loads(done.stdout)["path"])
    root = out / "kitti"
    (root / "training").mkdir(parents=True)
    for folder in ("label_2", "calib", "velodyne"):
        shutil.move(sweep / folder, root / "training" / folder)
    with (root / "training" / "label_2" / "000002.txt").open("a") as labels:
        labels.write(DONT_CARE)
    shutil.rmtree(out / "sweep")
    return root


@pytest.fixture(scope="session", params=["built", "real"])
def kitti_root(request) -> Path:
    """A KITTI folder for the format checks: the one built here (every clone) and the real
    sample (where it is found; skipped, saying so, elsewhere)."""
    return request.getfixturevalue("built_kitti" if request.param == "built" else "kitti_sample")


@pytest.fixture(scope="session")
def kitti_dataset(kitti_root, tmp_path_factory) -> Path:
    """``kitti_root`` converted with the defaults."""
    return convert_kitti(kitti_root, tmp_path_factory.mktemp("kitti"), progress=False)


@pytest.fixture(scope="session")
def real_kitti_dataset(kitti_sample, tmp_path_factory) -> Path:
    """The real KITTI sample converted with the defaults (the checks of its own numbers)."""
    return convert_kitti(kitti_sample, tmp_path_factory.mktemp("kitti-real"), progress=False)


def _write_frame(
    root: Path, stem: str, points: np.ndarray, labels: str, calib: str = SIMPLE_CALIB
) -> None:
    """One frame in the benchmark's layout under ``root/training``; points (n, 3) metres."""
    base = root / "training"
    for folder in ("velodyne", "label_2", "calib"):
        (base / folder).mkdir(parents=True, exist_ok=True)
    scan = np.zeros((len(points), 4), dtype="<f4")
    scan[:, :3] = points
    (base / "velodyne" / f"{stem}.bin").write_bytes(scan.tobytes())
    (base / "label_2" / f"{stem}.txt").write_text(labels)
    (base / "calib" / f"{stem}.txt").write_text(calib)


def _wall(x_m: float, ys_m: np.ndarray, zs_m: np.ndarray) -> np.ndarray:
    """Points (n, 3) on the plane x = x_m, one per (y, z) of the two grids."""
    y, z = np.meshgrid(ys_m, zs_m)
    return np.stack([np.full(y.size, x_m), y.ravel(), z.ravel()], axis=1)


@pytest.fixture
def synthetic_kitti(tmp_path) -> Path:
    """Three synthetic frames (SIMPLE_CALIB): 000000 a car 10 m straight behind the sensor
    with a wall of points on its near face at x = -9.5 m, 000001 a pedestrian 5 m ahead with
    a wall at x = 5 m, 000002 no objects (DontCare only)."""
    steps = np.arange(-0.75, 0.8, 0.1)
    # camera (0, 1, -10) = velodyne (-10, 0, -1): the box's bottom centre, 1 m below the sensor
    car = "Car 0.00 0 0.00 0 0 10 10 1.50 1.60 4.00 0.00 1.00 -10.00 0.00\n"
    _write_frame(tmp_path, "000000", _wall(-9.5, 2 * steps, steps), car)
    pedestrian = "Pedestrian 0.50 1 0.00 0 0 10 10 1.80 0.60 0.80 0.00 1.00 5.20 0.00\n"
    _write_frame(tmp_path, "000001", _wall(5.0, steps / 3, steps), pedestrian)
    dont_care = "DontCare -1 -1 -10 1 1 5 5 -1 -1 -1 -1000 -1000 -1000 -10\n"
    _write_frame(tmp_path, "000002", _wall(20.0, steps, steps), dont_care)
    return tmp_path
