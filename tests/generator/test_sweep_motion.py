"""Sweeps in motion (issue 59): every pulse cast at its own time along continuous sequences,
checked against numbers derived by hand through the whole pipeline (catalog, sweep file,
points, deskewing), and the same bytes for any batch."""

import hashlib
import json
from pathlib import Path

import h5py
import numpy as np
import pytest

from simlidar.generator.config import GeneratorConfig
from simlidar.generator.frames import deskewed_xyz, frame_points
from simlidar.generator.sweep import SweepConfig, sweep
from simlidar.motion.poses import PlanarMotion
from simlidar.scene.recipe import load_catalog
from simlidar.sensor import default_sensor


def _file(path):
    return path / "frames.h5"


def test_a_wall_seen_from_a_car_at_10_m_s_deskews_onto_its_plane(wall_catalog, tmp_path):
    """The issue's check: VLP-16 at 600 RPM on a car at 10 m/s, a wall's face at x = 20 m. Each
    point lies where its own pulse's time put the sensor, so the raw points of the wall spread
    over the car's travel while the head turns across it (the wall's 100 m span at 20 m is
    2 atan(50 / 20) = 136.4 deg of azimuth, 37.9 ms: 0.379 m at 10 m/s); moved to
    the frame's reference pose they lie on the plane x = 20 - 10 t_ref, within the range's 2 mm
    quantisation (its resolution, docs/sensor-model.md)."""
    config = GeneratorConfig(ego_speed_mps=10.0)
    path = sweep(config, SweepConfig(frames=2), wall_catalog, tmp_path, progress=False)
    assert path.name == "simlidar-sweep-32c-vlp16-2f-seed0-ego10.0-v1.4.0"
    with h5py.File(_file(path)) as f:
        wall = json.loads(f.attrs["surface_names"]).index("wall")
        pose, start_ns = f["ego_pose"][:], f["start_ns"][:]
        assert f.attrs["sequence_frames"] == 2 and (f["labels"][:] == 0).all()
    sensor = default_sensor()
    for frame in (0, 1):
        points = frame_points(_file(path), frame)
        on_wall = points["surface"] == wall
        assert on_wall.sum() > 5000
        t_s = (start_ns[frame] + points["t_ns"][on_wall]) * 1e-9
        reference_s = pose[frame, 0, 3] / 10.0  # the car's travel at the reference time
        raw_x = points["x"][on_wall].astype(np.float64)
        # raw: the plane as each pulse saw it, 20 m less the travel by then (2 mm quantised)
        np.testing.assert_allclose(raw_x, 20.0 - 10.0 * t_s, atol=0.002)
        # the wall's width as the head sweeps it; its ends come nearer as the car moves on
        assert np.ptp(t_s) == pytest.approx(2 * np.degrees(np.arctan2(50, 20)) / 3600, abs=1.5e-3)
        assert np.ptp(raw_x) == pytest.approx(10.0 * np.ptp(t_s), abs=0.004)
        deskewed = deskewed_xyz(_file(path), frame, points)[on_wall]
        np.testing.assert_allclose(deskewed[:, 0], 20.0 - 10.0 * reference_s, atol=0.002)
        assert np.ptp(deskewed[:, 0]) < 0.004
        np.testing.assert_allclose(deskewed[:, 1:], np.stack(
            [points["y"][on_wall], points["z"][on_wall]], -1), atol=1e-5)  # fmt: skip
    # the frames follow each other: one rotation of 60 / 600 s apart, the head turning on
    cycle_ns = sensor.cycle_us * 1000.0
    cycles = np.diff(start_ns) / cycle_ns
    assert cycles[0] in (1808.0, 1809.0) and start_ns[0] == 0.0
    np.testing.assert_allclose(np.diff(pose[:, 0, 3]), 10.0 * np.diff(start_ns) * 1e-9, atol=1e-12)
    np.testing.assert_array_equal(pose[:, :, :3], np.broadcast_to(np.eye(3), (2, 3, 3)))


def test_a_sequences_object_moves_as_drawn(tmp_path):
    """Sequences of 2 frames: sequence 1 is class 1 (tunnel, car); its car's box moves between
    the frames' reference times as its drawn speed, heading and yaw rate say."""
    catalog = load_catalog()
    config = GeneratorConfig(moving_objects=True)
    path = sweep(config, SweepConfig(frames=4, sequence_frames=2), catalog, tmp_path,
                 progress=False)  # fmt: skip
    assert path.name == "simlidar-sweep-32c-vlp16-4f-seed0-moving-seq2-v1.4.0"
    with h5py.File(_file(path)) as f:
        assert list(f["sequence"][:]) == [0, 0, 1, 1] and list(f["labels"][:]) == [0, 0, 1, 1]
        assert json.loads(f.attrs["motion"])["car"]["speed_mps"] == [3.0, 15.0]
        motion, box, pose = f["object_motion"][:], f["object_box"][:], f["object_pose"][:]
        start_ns, points = f["start_ns"][:], f["object_points"][:]
    np.testing.assert_array_equal(motion[:2], 0.0)  # sequence 0 has no object
    speed, heading, yaw_rate = (float(v) for v in motion[2])
    assert 3.0 <= speed <= 15.0 and heading in (0.0, 180.0) and -5.0 <= yaw_rate <= 5.0
    assert (points[2:] > 0).all()
    sensor = default_sensor()
    reference_s = start_ns[2:] * 1e-9 + 904 * sensor.cycle_us * 1e-6  # the middle cycle
    # where the box's centre was placed (the object's reference point at t = 0), moved
    moved = PlanarMotion(speed, yaw_rate, heading, tuple(pose[2, :2].astype(float)))
    # the box at placement is the frame's box moved back: compare the two frames' boxes
    placed = moved.poses(reference_s[0]).to_body(box[2, 3:6].astype(np.float64))
    np.testing.assert_allclose(
        moved.poses(reference_s[1]).to_scene(placed), box[3, 3:6], atol=2e-5
    )  # float32 boxes
    assert box[3, 6] - box[2, 6] == pytest.approx(yaw_rate * np.diff(reference_s)[0], abs=1e-4)
    travel = np.hypot(*(box[3, 3:5] - box[2, 3:5]))
    assert travel == pytest.approx(speed * 0.1, rel=0.01)  # a rotation apart


def test_any_batch_gives_the_same_bytes(tmp_path):
    catalog = load_catalog()
    config = GeneratorConfig(ego_speed_mps=5.0, ego_yaw_rate_deg_s=8.0, moving_objects=True)
    chosen = SweepConfig(frames=5, sequence_frames=3)
    digests = []
    for batch in (16, 2, 1):
        path = sweep(config, chosen, catalog, tmp_path / str(batch), progress=False, batch=batch)
        digests.append(hashlib.sha256(_file(path).read_bytes()).hexdigest())
    assert len(set(digests)) == 1


def test_standing_still_in_sequences_sees_the_same_scene_each_rotation(tmp_path):
    """No motion, sequences of 2: both frames show one scene; only the head's phase moves on."""
    path = sweep(GeneratorConfig(), SweepConfig(frames=2, sequence_frames=2), load_catalog(),
                 tmp_path, progress=False)  # fmt: skip
    assert path.name.endswith("-seq2-v1.4.0")
    with h5py.File(_file(path)) as f:
        assert f["labels"][0] == f["labels"][1] and (f["ego_pose"][:, :, 3] == 0).all()
        np.testing.assert_array_equal(f["object_pose"][0], f["object_pose"][1])  # NaN: none
        phase = f["phase"][:]
    per_rotation = 60e6 / 600 / default_sensor().cycle_us  # 1808.45 cycles
    assert phase[1] == pytest.approx((phase[0] - per_rotation) % 1.0, abs=1e-9)


@pytest.mark.parametrize(
    "options, expected",
    [
        (["--ego-speed", "-1"], "not in the range 0<=x<=70"),
        (["--ego-speed", "nan"], "--ego-speed"),
        (["--ego-yaw-rate", "400"], "--ego-yaw-rate"),
        (["--ego-speed", "30", "--frames", "200"], "600 m from the scene's origin; expected"),
        (["--sequence-frames", "-2"], "--sequence-frames"),
    ],
)
def test_bad_motion_is_one_line_and_writes_nothing(options, expected, tmp_path, cli, refused):
    result = cli("sweep", "--frames", "2", *options, "--out", tmp_path / "o")
    refused(result, tmp_path / "o", expected)


def test_moving_objects_need_a_motion_table(catalog_copy, tmp_path, cli):
    (catalog_copy / "motion.toml").unlink()
    result = cli("sweep", "--moving-objects", "--scenes", catalog_copy, "--out", tmp_path / "o")
    assert result.exit_code == 2 and "has no motion.toml" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and not (tmp_path / "o").exists()


def test_a_trajectory_file_of_a_straight_drive_is_that_drive(tmp_path, cli):
    """Two rows, 0 s at the origin and 1 s 10 m ahead, interpolate to 10 t: the points, the
    poses and the deskewed scans are those of --ego-speed 10 to the bit."""
    rows = tmp_path / "drive.txt"
    rows.write_text("# t x y z roll pitch yaw\n0 0 0 0 0 0 0\n1.0, 10, 0, 0, 0, 0, 0\n")
    made = {}
    for name, options in (("file", ["--trajectory", rows]), ("speed", ["--ego-speed", "10"])):
        result = cli("sweep", "--frames", "2", *options, "--export", "kitti", "--out",
                     tmp_path / name, "--json")  # fmt: skip
        assert result.exit_code == 0, result.output
        made[name] = json.loads(result.stdout)["path"]
    assert "-traj" in made["file"] and made["file"].endswith("-v1.4.0")
    with h5py.File(f"{made['file']}/frames.h5") as a, h5py.File(f"{made['speed']}/frames.h5") as b:
        assert a["ego_trajectory"].shape == (2, 8)
        assert json.loads(a.attrs["config"])["ego_trajectory"]["rows"] == 2
        for name in ("range_m", "surface", "intensity", "ego_pose", "start_ns", "phase"):
            np.testing.assert_array_equal(a[name][:], b[name][:], err_msg=name)
    for frame in ("000000", "000001"):
        scans = [(tmp_path / n / Path(made[n]).name / "velodyne" / f"{frame}.bin").read_bytes()
                 for n in ("file", "speed")]  # fmt: skip
        assert scans[0] == scans[1]


@pytest.mark.parametrize(
    "text, expected",
    [
        ("0 0 0 0 0 0 0\n0.1 1 0 0 0 0 0\n", "expected them to cover the simulated span"),
        ("0 0 0 0 0 0 0\n1 0 0 0 0 0 nan\n", "line 2"),
        ("0 0 0 0 0 0 0\n", "expected at least 2"),
        ("0 0 0 0 0 0 0\n0.2 500 0 0 0 0 0\n", "500 m from the scene's origin; expected"),
    ],
)
def test_a_bad_trajectory_is_one_line_and_writes_nothing(text, expected, tmp_path, cli):
    rows = tmp_path / "bad.txt"
    rows.write_text(text)
    result = cli("sweep", "--frames", "2", "--trajectory", rows, "--out", tmp_path / "o")
    assert result.exit_code == 2, result.output
    assert expected in result.stderr and len(result.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "o").exists()


def test_a_trajectory_and_a_speed_together_are_refused(tmp_path, cli):
    rows = tmp_path / "drive.txt"
    rows.write_text("0 0 0 0 0 0 0\n1 10 0 0 0 0 0\n")
    result = cli("sweep", "--trajectory", rows, "--ego-speed", "3", "--out", tmp_path / "o")
    assert result.exit_code == 2 and "expected one way of moving the ego" in result.stderr


def test_a_sequence_the_objects_could_carry_out_of_the_cell_is_refused_first(tmp_path, cli):
    """A car of motion.toml at up to 15 m/s over 100 frames (10 s) could carry the sensor 150 m
    in its own frame: refused before anything is cast, where it failed at frame 160."""
    result = cli("sweep", "--frames", "200", "--sequence-frames", "100", "--moving-objects",
                 "--out", tmp_path / "o")  # fmt: skip
    assert (
        result.exit_code == 2 and "and the objects' motion over a sequence of 100" in result.stderr
    )
    assert len(result.stderr.strip().splitlines()) == 1 and not (tmp_path / "o").exists()


def test_a_car_driving_through_the_sensor_gives_the_same_frames_in_any_batch():
    """Sequence 3 (a truck, seed 0) drives through the moving sensor: with back
    faces culled over a batch's origins, frames 6-8 of the batch held three times the object
    returns they had cast alone. A moving cast culls nothing: the same frames either way."""
    from simlidar.generator.sweep import simulate_frames

    catalog = load_catalog()
    config = GeneratorConfig(ego_speed_mps=10.0, moving_objects=True)
    batch = simulate_frames(config, catalog, 48, 64, sequence=16)
    for f in (6, 7, 8):
        alone = simulate_frames(config, catalog, 48 + f, 49 + f, sequence=16)
        np.testing.assert_array_equal(alone.range_m[0], batch.range_m[f])
        np.testing.assert_array_equal(alone.surface[0], batch.surface[f])
        assert alone.object_points[0] == batch.object_points[f] > 0
