"""Fixtures of the converter tests: KITTI training folders (one built here from a simulated
sweep, in every clone; the real sample, read in place and never copied, where it is), their
converted datasets, and small synthetic inputs the tests write themselves."""

import os
from pathlib import Path

import pytest

from simlidar.convert import convert_kitti

ROOT = Path(__file__).resolve().parents[2]
KITTI_SAMPLE = Path(
    os.environ.get("SIMLIDAR_KITTI_SAMPLE", ROOT / ".." / "shared" / "data" / "kitti-sample")
)


@pytest.fixture(scope="session")
def kitti_sample() -> Path:
    """The three real frames of ../shared/data/kitti-sample (or $SIMLIDAR_KITTI_SAMPLE)."""
    if not (KITTI_SAMPLE / "training" / "velodyne").is_dir():
        pytest.skip(
            f"KITTI sample not found at {KITTI_SAMPLE}: set SIMLIDAR_KITTI_SAMPLE to the folder "
            "holding training/ (three frames of the 3D object benchmark)"
        )
    return KITTI_SAMPLE


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
