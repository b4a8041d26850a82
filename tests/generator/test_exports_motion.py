"""The KITTI export of sweeps in motion (issue 59): odometry poses, tracking labels and instance
ids, checked against numbers derived by hand (the VLP-16 fires a cycle every 55.296 us, 1808.45
cycles a rotation at 600 RPM) and read back with the KITTI converter's own readers; sweeps that
do not move export as before."""

import json
import math

import h5py
import numpy as np
import pytest

from simlidar.convert.kitti import training_files
from simlidar.convert.kitti_files import box_corners_cam, inside_box, read_frames, to_velo
from simlidar.errors import DatasetError
from simlidar.generator.config import GeneratorConfig
from simlidar.generator.exports import export_frame
from simlidar.generator.frames import frame_points
from simlidar.generator.sweep import SweepConfig, sweep
from simlidar.sensor import default_sensor

CYCLE_S = 55.296e-6  # the VLP-16's firing cycle (user manual 63-9243 Rev D)
CYCLES = 60e6 / 600 / 55.296  # cycles a rotation at 600 RPM: 1808.449...
MIDDLE = 904  # a frame's reference cycle: the middle of its 1808
MOUNT_M = default_sensor().mount_height_m  # the sensor above the rig's origin (1.8 m)
FIELDS = ("sequence", "start_ns", "phase", "object_box", "object_points", "object_motion")


def _sweep(out, catalog, frames, **motion):
    config = GeneratorConfig(**motion)
    every = SweepConfig(frames=frames, sequence_frames=frames // 2 if frames > 2 else 0)
    return sweep(config, every, catalog, out, exports=("kitti",), progress=False)


@pytest.fixture(scope="module")
def drive(tmp_path_factory, catalog):
    """Two sequences of two frames at 10 m/s, the objects moving: sequence 0 shows class 0 (a
    tunnel, no object), sequence 1 class 1 (a tunnel with a car)."""
    out = tmp_path_factory.mktemp("drive")
    return _sweep(out, catalog, 4, ego_speed_mps=10.0, moving_objects=True)


def _read(path):
    """The frames' FIELDS, and the car's surface index."""
    with h5py.File(path / "frames.h5") as f:
        car = json.loads(f.attrs["surface_names"]).index("car")
        return {name: f[name][:] for name in FIELDS} | {"car": car}


def _poses(path) -> np.ndarray:
    """poses.txt as KITTI's odometry devkit reads it: (frames, 3, 4)."""
    return np.loadtxt(path / "poses.txt", ndmin=2).reshape(-1, 3, 4)


def test_poses_of_a_straight_drive_are_its_travel_ahead_in_camera_axes(drive):
    """KITTI's poses are the camera's, z ahead: at 10 m/s the second frame of a sequence is 10 m/s
    times the time between the reference cycles ahead of the first, 1808 or 1809 cycles as the
    sequence's phase says (0.99975 or 1.00030 m); each sequence restarts at the identity."""
    frames, poses = _read(drive), _poses(drive)
    assert poses.shape == (4, 3, 4) and list(frames["sequence"]) == [0, 0, 1, 1]
    for first in (0, 2):
        cycles = math.ceil(CYCLES - frames["phase"][first])  # frame 1 of the sequence
        assert cycles in (1808, 1809)
        travel_m = 10.0 * cycles * CYCLE_S
        np.testing.assert_array_equal(poses[first], np.eye(3, 4))
        np.testing.assert_array_equal(poses[first + 1, :, :3], np.eye(3))
        np.testing.assert_allclose(poses[first + 1, :, 3], [0.0, 0.0, travel_m], rtol=1e-6)


def test_a_turn_is_a_rotation_about_the_camera_s_vertical(tmp_path, catalog):
    """10 m/s turning left at 30 deg/s: between the reference times, dt apart, the sensor turns
    by a = 30 dt degrees about the up axis, the camera's -y, and moves along the arc's chord
    2 v / w sin(a / 2) at a / 2 to the left of ahead, camera (-sin, 0, cos)."""
    path = _sweep(tmp_path, catalog, 2, ego_speed_mps=10.0, ego_yaw_rate_deg_s=30.0)
    frames, poses = _read(path), _poses(path)
    dt = (frames["start_ns"][1] - frames["start_ns"][0]) * 1e-9
    a = math.radians(30.0 * dt)
    chord = 2 * 10.0 / math.radians(30.0) * math.sin(a / 2)
    c, s = math.cos(a), math.sin(a)
    expected = [
        [c, 0, -s, -chord * math.sin(a / 2)],
        [0, 1, 0, 0],
        [s, 0, c, chord * math.cos(a / 2)],
    ]
    np.testing.assert_allclose(poses[1], expected, rtol=1e-5, atol=1e-6)


def test_a_pitching_rig_carries_its_sensor_by_its_mount(tmp_path, catalog):
    """A rig standing still that pitches at 25 deg/s (a trajectory file: ROS's pitch, nose
    down): the sensor, 1.8 m above the rig's origin, turns by p = 25 dt degrees and swings
    forward and down about that origin by (h sin p, 0, h (cos p - 1)), camera (0, h (1 - cos p),
    h sin p): the rig's pose composed with the mount, not the rig's pose alone."""
    rows = tmp_path / "pitch.txt"
    rows.write_text("# t x y z roll pitch yaw\n0 0 0 0 0 0 0\n1 0 0 0 0 25 0\n")
    from simlidar.motion.trajectory import load_trajectory

    path = _sweep(tmp_path, catalog, 2, ego_trajectory=load_trajectory(rows))
    frames, poses = _read(path), _poses(path)
    p = math.radians(25.0 * (frames["start_ns"][1] - frames["start_ns"][0]) * 1e-9)
    c, s, h = math.cos(p), math.sin(p), MOUNT_M
    expected = [[1, 0, 0, 0], [0, c, s, h * (1 - c)], [0, -s, c, h * s]]
    assert h * s > 0.07  # what the mount adds: 7.8 cm
    np.testing.assert_allclose(poses[1], expected, rtol=1e-5, atol=1e-6)


def test_tracking_labels_put_the_car_where_each_frame_s_sensor_sees_it(drive):
    """label_02/0001.txt: the car of sequence 1 in its frames 0 and 1, track 0, its box at each
    frame's reference time (start + 904 cycles) seen from the sensor then: ahead (camera z) by
    its scene x less the ego's 10 m/s travel, right (camera x) by -y, down (camera y) by the
    1.8 m mount less its bottom's height; the same line as the frame's label_2 file."""
    frames = _read(drive)
    assert (drive / "label_02" / "0000.txt").read_bytes() == b""  # sequence 0: no object
    lines = (drive / "label_02" / "0001.txt").read_text().splitlines()
    assert len(lines) == 2
    for step, line in enumerate(lines):
        frame = 2 + step
        fields = line.split()
        assert fields[:3] == [str(step), "0", "Car"] and len(fields) == 17
        t_ref = frames["start_ns"][frame] * 1e-9 + MIDDLE * CYCLE_S
        length, width, height, x, y, z, yaw = frames["object_box"][frame].astype(float)
        ahead = x - 10.0 * t_ref
        assert ahead < x - 0.49  # the ego has travelled 0.5 m by the first reference time
        ry = (-math.radians(yaw) - math.pi / 2 + math.pi) % (2 * math.pi) - math.pi
        expected = [height, width, length, -y, MOUNT_M - z, ahead, ry]
        np.testing.assert_allclose([float(v) for v in fields[10:]], expected, atol=6e-5)
        assert " ".join(fields[2:]) + "\n" == (drive / "label_2" / f"{frame:06d}.txt").read_text()


def test_the_deskewed_car_lies_in_its_label_s_box(drive):
    """Read back as the KITTI converter reads the folder (label_2, calib, velodyne): every point
    of the car's surface lies in its label's box, grown by the 2 mm range quantisation and by
    the car's own travel between a point's time and the reference time (the scan is deskewed
    for the ego's motion only, as KITTI's are)."""
    frames = _read(drive)
    read = {f.number: f for f in read_frames(training_files(drive))}
    for frame in (2, 3):
        (label,) = read[frame].labels
        points = frame_points(drive / "frames.h5", frame)
        scan = np.fromfile(drive / "velodyne" / f"{frame:06d}.bin", "<f4").reshape(-1, 4)
        car = points["surface"] == frames["car"]
        t_ref_ns = MIDDLE * CYCLE_S * 1e9
        margin = (
            0.004
            + frames["object_motion"][frame, 0]
            * np.abs(points["t_ns"][car] - t_ref_ns).max()
            * 1e-9
        )
        h, w, length, x, y, z, ry = label.box
        grown = (h + 2 * margin, w + 2 * margin, length + 2 * margin, x, y + margin, z, ry)
        corners = to_velo(box_corners_cam(grown), read[frame].cam_to_velo)
        assert car.sum() > 100 and inside_box(scan[car, :3].astype(float), corners).all()


def test_instance_ids_mark_the_labelled_object_s_points(drive):
    """SemanticKITTI's .label: the surface in the lower 16 bits as before, instance 1 in the
    upper 16 on the car's points, as many as the sweep counted returns from its object
    (object_points, counted while casting); none in sequence 0's frames, which have no object."""
    frames = _read(drive)
    for frame in range(4):
        labels = np.fromfile(drive / "labels" / f"{frame:06d}.label", "<u4")
        surface = frame_points(drive / "frames.h5", frame)["surface"]
        np.testing.assert_array_equal(labels & 0xFFFF, surface)
        np.testing.assert_array_equal(labels >> 16, surface == frames["car"])
        assert (labels >> 16).sum() == frames["object_points"][frame]
        assert ((labels >> 16).sum() > 0) == (frame >= 2)


def _ply(path) -> np.ndarray:
    """A binary little-endian PLY's vertices, by its header's properties."""
    blob = path.read_bytes()
    head, body = blob.split(b"end_header\n", 1)
    types = {"float": "<f4", "double": "<f8", "uchar": "u1", "ushort": "<u2"}
    fields = [
        (line.split()[2], types[line.split()[1]])
        for line in head.decode().splitlines()
        if line.startswith("property")
    ]
    return np.frombuffer(body, np.dtype(fields))


def test_ply_and_pcd_points_carry_their_time_deskewed_coordinates_and_instance(drive, tmp_path):
    """In motion the PLY and PCD points keep their raw coordinates and time and add their
    deskewed coordinates (the KITTI scan's, to the float32) and instance id (the label's
    upper 16 bits); the PCD holds the PLY's bytes after its own header."""
    for frame in (0, 3):
        ply = export_frame(drive / "frames.h5", frame, tmp_path, "ply")[0]
        pcd = export_frame(drive / "frames.h5", frame, tmp_path, "pcd")[0]
        points = _ply(ply)
        raw = frame_points(drive / "frames.h5", frame)
        for name in raw.dtype.names:
            np.testing.assert_array_equal(points[name], raw[name])
        scan = np.fromfile(drive / "velodyne" / f"{frame:06d}.bin", "<f4").reshape(-1, 4)
        np.testing.assert_array_equal(
            np.stack([points[k] for k in ("x_deskewed", "y_deskewed", "z_deskewed")], -1),
            scan[:, :3],
        )
        labels = np.fromfile(drive / "labels" / f"{frame:06d}.label", "<u4")
        np.testing.assert_array_equal(points["instance"], labels >> 16)
        assert (points["instance"].sum() > 0) == (frame >= 2)
        assert not np.array_equal(points["x"], points["x_deskewed"])  # 10 m/s: they differ
        head = pcd.read_bytes().split(b"DATA binary\n", 1)
        assert (
            b"FIELDS x y z intensity surface laser t_ns x_deskewed y_deskewed z_deskewed instance"
            in head[0]
            and b"SIZE 4 4 4 4 1 1 8 4 4 4 2" in head[0]
        )
        assert head[1] == points.tobytes()


def test_frames_exported_in_any_order_write_the_same_files(drive, tmp_path):
    """The frame that ends a sequence writes its tracking labels, the sweep's last frame
    poses.txt: exporting the frames backwards gives the sweep's export byte for byte."""
    written = {}
    for frame in reversed(range(4)):
        files = export_frame(drive / "frames.h5", frame, tmp_path, "kitti")
        written[frame] = [p.relative_to(tmp_path).as_posix() for p in files[4:]]
    assert written == {
        3: ["label_02/0001.txt", "poses.txt"],
        2: [],
        1: ["label_02/0000.txt"],
        0: [],
    }
    for made in tmp_path.rglob("*"):
        if made.is_file():
            assert made.read_bytes() == (drive / made.relative_to(tmp_path)).read_bytes()


def test_a_sweep_that_does_not_move_exports_as_before(tmp_path, catalog):
    """No poses, no tracking labels, no instance ids: the files a static sweep exported before
    (checked by diff -r against the previous commit as well)."""
    path = _sweep(tmp_path, catalog, 2)
    assert path.name.endswith("-v1.1.0")
    assert sorted(p.name for p in path.iterdir()) == [
        "bev.png", "calib", "frames.h5", "label_2", "labels", "velodyne"]  # fmt: skip
    for frame in (0, 1):
        labels = np.fromfile(path / "labels" / f"{frame:06d}.label", "<u4")
        surface = frame_points(path / "frames.h5", frame)["surface"]
        np.testing.assert_array_equal(labels, surface)


@pytest.mark.parametrize("value", [0, -2, 2.5, "2"])
def test_a_sweep_file_with_a_bad_sequence_length_is_one_line_and_writes_nothing(
    drive, tmp_path, value
):
    """A frames.h5 whose sequence_frames is no whole number of frames (a file from elsewhere)
    is refused naming the value, before any file of the frame is written."""
    copy = tmp_path / "frames.h5"
    copy.write_bytes((drive / "frames.h5").read_bytes())
    with h5py.File(copy, "r+") as f:
        f.attrs["sequence_frames"] = value
    out = tmp_path / "out"
    with pytest.raises(DatasetError, match=r"sequence_frames=.*expected a whole number >= 1"):
        export_frame(copy, 3, out, "kitti")
    assert not out.exists()
