"""Windows in motion (issue 59, item 4): ``generate --timing scan`` with a moving ego and
moving objects, every pulse of a window cast at its own emission time; checked against numbers
derived by hand, against an equivalent motion, and for the same bytes in any batch."""

import hashlib
import json
import subprocess
import sys
from dataclasses import replace

import h5py
import numpy as np
import pytest

from simlidar.data import load_split
from simlidar.dataset.reader import read_split
from simlidar.errors import ConfigError
from simlidar.generator.config import GeneratorConfig
from simlidar.generator.generate import generate
from simlidar.generator.simulate import simulate
from simlidar.scene.recipe import load_catalog
from simlidar.sensor.model import SPEED_OF_LIGHT_M_PER_S
from simlidar.sensor.rays import window_rays

SCAN = dict(classes=4, train_size=8, test_size=8, timing="scan")


def _ranges_m(samples) -> np.ndarray:
    return samples.tof_ns.astype(np.float64) * 1e-9 * SPEED_OF_LIGHT_M_PER_S / 2.0


def test_a_wall_20_m_ahead_comes_nearer_as_each_pulse_leaves(wall_catalog):
    """A wall's face at x = 20 m across the road, the ego at 10 m/s: a pulse of direction d
    fired t after the window's first one meets the wall v t / d_x sooner than the standing
    sensor's (it left from v t further on), within the range's 2 mm quantisation. The same
    seed gives the same scene (no object: nothing more is drawn), so the two differ by the
    motion alone; across the 16 columns of 36 deg (10 ms at 600 RPM) that is up to 10 cm."""
    config = GeneratorConfig(classes=32, train_size=32, test_size=32, timing="scan")
    moving = replace(config, ego_speed_mps=10.0)
    wall = wall_catalog.surfaces.index("wall")
    for index in (0, 32):  # class 0: the wall's layout, no object
        still = simulate(config, wall_catalog, "train", index, index + 1)
        seen = simulate(moving, wall_catalog, "train", index, index + 1)
        np.testing.assert_array_equal(still.phase, seen.phase)
        np.testing.assert_array_equal(still.emission_ns, seen.emission_ns)
        both = (still.surface == wall) & (seen.surface == wall)
        assert both.sum() > 100
        _, directions = window_rays(config.sensor, config.width, config.fov_deg, still.phase)
        t_s = seen.emission_ns * 1e-9
        nearer = 10.0 * t_s / directions[..., 0]  # the travel along the ray to the plane
        got = _ranges_m(still) - _ranges_m(seen)
        np.testing.assert_allclose(got[both], nearer[both], atol=0.002 + 1e-5)
        assert nearer[both].max() > 0.08  # the window's last pulses: 10 ms on
        np.testing.assert_array_equal(seen.ego_motion, [[10.0, 0.0]])


@pytest.fixture
def oncoming_catalog(catalog_copy):
    """The shipped catalog whose cars come toward the sensor at 10 m/s, straight."""
    (catalog_copy / "motion.toml").write_text("[car]\nspeed_mps = 10.0\nheading_deg = 180.0\n")
    return load_catalog(catalog_copy)


def test_an_oncoming_car_is_seen_as_a_car_ahead_by_an_ego_driving_at_it(oncoming_catalog):
    """A car coming at 10 m/s toward a standing sensor and a standing car approached at
    10 m/s: the same relative motion, so every pulse that meets the car in both meets it at
    the same range (within the 2 mm quantisation), though the road and the walls differ.
    Each draw reads the scene's parameters first, so a sample accepted at its first draw has
    the same scene in both."""
    config = GeneratorConfig(classes=32, train_size=32, test_size=32, timing="scan")
    things = replace(config, moving_objects=True)
    ego = replace(config, ego_speed_mps=10.0)
    car = oncoming_catalog.surfaces.index("car")
    compared = 0
    for start in (0, 32, 64):  # classes 1, 5, 9, ...: a car in every layout
        a = simulate(things, oncoming_catalog, "train", start, start + 32)
        b = simulate(ego, oncoming_catalog, "train", start, start + 32)
        for k in np.nonzero((a.object == 1) & (a.attempts == 1) & (b.attempts == 1))[0]:
            np.testing.assert_array_equal(a.object_pose[k], b.object_pose[k])
            np.testing.assert_array_equal(a.object_motion[k], [10.0, 180.0, 0.0])
            np.testing.assert_array_equal(b.object_motion[k], [0.0, 0.0, 0.0])
            both = (a.surface[k] == car) & (b.surface[k] == car)
            np.testing.assert_allclose(
                _ranges_m(a)[k][both], _ranges_m(b)[k][both], atol=0.002 + 1e-5
            )
            compared += int(both.sum())
    assert compared > 200


def _digests(folder) -> dict[str, str]:
    return {
        p.name: hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def test_the_same_bytes_for_every_batch_size_and_worker_count(tmp_path):
    """A moving dataset's files do not depend on how it was cut: batch sizes 3 and 64 (capped
    at MAX_BATCH / 2 in motion) and two workers give the same bytes."""
    catalog = load_catalog()
    config = GeneratorConfig(**SCAN, ego_speed_mps=15.0, ego_yaw_rate_deg_s=20.0,
                             moving_objects=True)  # fmt: skip
    runs = [
        generate(config, [0.1], catalog, tmp_path / "a", batch_size=3, progress=False)[0].path,
        generate(config, [0.1], catalog, tmp_path / "b", batch_size=64, progress=False)[0].path,
        generate(config, [0.1], catalog, tmp_path / "c", workers=2, progress=False)[0].path,
    ]
    assert runs[0].name == "simlidar-4c-noise0.1-physical-scan-ego15.0-yaw20.0-moving-v4.3.0"
    assert _digests(runs[0]) == _digests(runs[1]) == _digests(runs[2])


def test_a_moving_dataset_stores_its_motion_and_passes_verify(tmp_path):
    """The split holds each sample's drawn motion and the ego's, the configuration and the
    motion table used; verify and the loaders accept it; the card names the motion and the
    command that writes it again, which does, byte for byte."""
    catalog = load_catalog()
    config = GeneratorConfig(**SCAN, ego_speed_mps=5.0, moving_objects=True)
    path = generate(config, [0.2], catalog, tmp_path / "a", progress=False)[0].path
    info = read_split(path, "train")
    assert info.attrs["dataset_version"] == "4.3.0"
    assert info.attrs["motion"]["pedestrian"]["heading_deg"] == {"choice": [90.0, -90.0]}
    assert info.attrs["config"]["moving_objects"] is True
    with h5py.File(path / "train.h5") as f:
        motion, obj, ego = f["object_motion"][:], f["object"][:], f["ego_motion"][:]
    np.testing.assert_array_equal(motion[obj == 0], 0.0)
    speeds = {1: (3.0, 15.0), 2: (1.0, 1.6), 3: (3.0, 12.0)}  # car, pedestrian, truck
    for oid, (low, high) in speeds.items():
        assert ((motion[obj == oid, 0] >= low) & (motion[obj == oid, 0] <= high)).all()
    np.testing.assert_array_equal(ego, np.tile([5.0, 0.0], (8, 1)))
    x, y = load_split(path, "train")
    assert x.shape == (8, 16, 16) and list(y) == [0, 1, 2, 3] * 2
    verified = subprocess.run([sys.executable, "-m", "simlidar.cli", "verify", str(path)],
                              capture_output=True, text=True)  # fmt: skip
    assert verified.returncode == 0, verified.stderr
    card = (path / "README.md").read_text()
    assert "In motion: the ego vehicle drives at 5.0 m/s" in card
    command = next(line for line in card.splitlines() if line.startswith("simlidar generate"))
    assert command.endswith("--timing scan --ego-speed 5.0 --moving-objects")
    again = subprocess.run(
        [sys.executable, "-m", "simlidar.cli", *command.split()[1:], "--out", str(tmp_path / "b")],
        capture_output=True, text=True,
    )  # fmt: skip
    assert again.returncode == 0, again.stderr
    assert _digests(path) == _digests(tmp_path / "b" / path.name)


def test_a_still_dataset_is_not_touched_by_the_motion_options():
    """Speed 0 and no moving objects: the configuration stores no motion key, and its
    version is the static one."""
    config = GeneratorConfig(**SCAN, ego_speed_mps=0.0, moving_objects=False)
    assert not config.moves
    assert not {"ego_speed_mps", "moving_objects"} & config.to_dict().keys()


@pytest.mark.parametrize(
    "fields, words",
    [
        (dict(timing="flash", ego_speed_mps=5.0), "expected --timing scan"),
        (dict(timing="flash", moving_objects=True), "with timing='flash'"),
    ],
)
def test_motion_windows_needs_scan_timing(tmp_path, fields, words):
    config = GeneratorConfig(**{**SCAN, **fields})
    with pytest.raises(ConfigError, match=words):
        generate(config, [0.2], load_catalog(), tmp_path, progress=False)
    assert not any(tmp_path.iterdir())


def test_a_trajectory_file_is_a_sweeps_not_a_windows(tmp_path):
    from simlidar.motion.trajectory import load_trajectory

    rows = tmp_path / "drive.txt"
    rows.write_text("0 0 0 0 0 0 0\n1 10 0 0 0 0 0\n")
    config = GeneratorConfig(**SCAN, ego_trajectory=load_trajectory(rows, "drive.txt"))
    with pytest.raises(ConfigError, match="expected --ego-speed and --ego-yaw-rate for windows"):
        generate(config, [0.2], load_catalog(), tmp_path / "out", progress=False)
    assert not (tmp_path / "out").exists()


def test_moving_objects_need_a_motion_table(tmp_path, catalog_copy):
    (catalog_copy / "motion.toml").unlink()
    config = GeneratorConfig(**SCAN, moving_objects=True)
    with pytest.raises(ConfigError, match="has no motion.toml"):
        generate(config, [0.2], load_catalog(catalog_copy), tmp_path / "out", progress=False)
    assert not (tmp_path / "out").exists()


def test_the_cli_refuses_motion_under_flash_timing_in_one_line(tmp_path):
    done = subprocess.run(
        [sys.executable, "-m", "simlidar.cli", "generate", "--classes", "4", "--train-size",
         "8", "--test-size", "8", "--ego-speed", "5", "--out", str(tmp_path / "out")],
        capture_output=True, text=True,
    )  # fmt: skip
    assert done.returncode != 0
    assert "expected --timing scan" in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1 and "Traceback" not in done.stderr
    assert not (tmp_path / "out").exists()


def test_a_moving_batch_is_at_most_half_the_caster_cells():
    config = GeneratorConfig(**SCAN, ego_speed_mps=1.0)
    with pytest.raises(ConfigError, match="expected 1..2048"):
        simulate(config, load_catalog(), "train", 0, 2049)
    assert json.loads(config.to_json())["ego_speed_mps"] == 1.0
