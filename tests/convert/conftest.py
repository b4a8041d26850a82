"""Fixtures of the converter tests: KITTI training folders (one built here from a simulated
sweep, in every clone; the real sample, read in place and never copied, where it is), their
converted datasets, and small synthetic inputs the tests write themselves."""

import json
import os
import shutil
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


# A DontCare line as KITTI writes them (the real sample's frame 000001 has two): skipped.
DONT_CARE = "DontCare -1 -1 -10 503.89 169.71 590.61 190.13 -1 -1 -1 -1000 -1000 -1000 -10\n"


@pytest.fixture(scope="session")
def built_kitti(tmp_path_factory, cli) -> Path:
    """A KITTI training folder made here, so that the format checks run in any clone: 8 frames
    of an HDL-64E sweep exported in KITTI's layout (`simlidar sweep --export kitti`: label_2/,
    calib/, velodyne/; 6 frames with a car, pedestrian or truck, 2 without), moved under
    ``training/`` without the sweep's frames.h5, so that the converter reads them as recorded
    frames, plus a DontCare line in frame 000002."""

    out = tmp_path_factory.mktemp("built-kitti")
    args = ["sweep", "--frames", "8", "--sensor", "hdl64e", "--export", "kitti"]
    done = cli(*args, "--out", str(out / "sweep"), "--json")
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
