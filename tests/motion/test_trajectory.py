"""Trajectory files (issue 59, item 1): the ego's poses read from rows ``t x y z roll pitch
yaw`` and interpolated per pulse, against numbers derived by hand and against PlanarMotion's
closed form.

Attack list: a file that is not one (a named pipe, a folder, too large, not UTF-8), rows of the
wrong length, values that are not finite decimal numbers (NaN, inf, 1e400, 0x10, 1_000, digits
of other scripts, an empty field), times that do not increase or lie beyond float64's pulse
resolution, positions in other units or origins (UTM), angles that wrap between two rows, too
many rows, a line of a million digits; times outside the rows asked of the poses.
"""

import math
import os
import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from simlidar.errors import ConfigError
from simlidar.motion import trajectory
from simlidar.motion.poses import PlanarMotion, yaw_rotation
from simlidar.motion.rotations import quaternion_from_rpy, rotation_from_quaternion
from simlidar.motion.trajectory import (
    MAX_TRAJECTORY_BYTES,
    Trajectory,
    load_trajectory,
)


def write(tmp_path, text: str, name: str = "drive.txt"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def refusal(path, **kwargs) -> str:
    """The one-line message of the ConfigError that loading ``path`` raises."""
    with pytest.raises(ConfigError) as caught:
        load_trajectory(path, **kwargs)
    message = str(caught.value)
    assert "\n" not in message and len(message) < 400, message
    return message


def test_halfway_between_two_rows_by_hand(tmp_path):
    """From the origin facing +x at 0 s to x = 10 m facing +y at 1 s: half way, x = 5 m and a
    yaw of 45 degrees."""
    drive = load_trajectory(write(tmp_path, "0 0 0 0 0 0 0\n1 10 0 0 0 0 90\n"))
    halfway = drive.poses(0.5)
    assert halfway.translation_m.tolist() == [5.0, 0.0, 0.0]
    c = s = math.sqrt(0.5)
    np.testing.assert_allclose(
        halfway.rotation, [[c, -s, 0], [s, c, 0], [0, 0, 1]], rtol=0, atol=1e-15
    )
    ends = drive.poses(np.array([0.0, 1.0]))
    assert ends.translation_m.tolist() == [[0.0, 0.0, 0.0], [10.0, 0.0, 0.0]]
    np.testing.assert_allclose(
        ends.rotation, [np.eye(3), [[0, -1, 0], [1, 0, 0], [0, 0, 1]]], rtol=0, atol=1e-15
    )


def test_at_each_row_time_the_rows_pose_exactly(tmp_path):
    rows = [
        (0.0, 0.0, 0.0, 1.8, 0.0, 0.0, 0.0),
        (0.013, 0.17, -0.02, 1.81, 1.5, -2.25, 3.0),
        (0.5, 4.9, 0.3, 1.79, -0.75, 0.5, 95.0),
        (0.5000001, 4.9000013, 0.3, 1.8, -0.75, 0.5, 95.0001),
        # 1.8 + (0.1 - 1.8) is not 0.1 in float64: p0 + f (p1 - p0) would miss this row
        (2.0, 20.0, -3.0, 0.1, 0.0, 0.0, -60.0),
    ]
    path = write(tmp_path, "".join(" ".join(map(repr, row)) + "\n" for row in rows))
    drive = load_trajectory(path)
    values = np.array(rows)
    at_rows = drive.poses(values[:, 0])
    assert np.array_equal(at_rows.translation_m, values[:, 1:4])
    expected = rotation_from_quaternion(quaternion_from_rpy(*values[:, 4:].T))
    assert np.array_equal(at_rows.rotation, expected)


def test_a_straight_drive_sampled_coarsely_is_planar_motion_exactly(tmp_path):
    """8 m/s along x, rows at 0, 0.5, 1 and 2 s only: at every time the poses of
    PlanarMotion(8 m/s), to the bit (times in 1/1024 s, so that every product is exact)."""
    rows = "".join(f"{t} {8 * t} 0 0 0 0 0\n" for t in (0.0, 0.5, 1.0, 2.0))
    drive = load_trajectory(write(tmp_path, rows))
    times = (np.arange(2049) / 1024).reshape(3, 683)  # a frame's (H, C)-like shape
    got, want = drive.poses(times), PlanarMotion(speed_mps=8.0).poses(times)
    assert got.rotation.shape == (3, 683, 3, 3) and got.translation_m.shape == (3, 683, 3)
    assert np.array_equal(got.rotation, want.rotation)
    assert np.array_equal(got.translation_m, want.translation_m)


def test_a_turning_drive_sampled_at_1_khz_follows_planar_motion(tmp_path):
    """10 m/s turning at 30 deg/s, rows every 1 ms for 1 s. Between two rows the car's point
    moves on the chord of its arc, radius r = v / w = 19.1 m, turning w dt = 5.2e-4 rad: off by
    at most the sagitta r (w dt)^2 / 8 = 0.65 um, far inside the 2 mm range resolution of the
    VLP-16 (the issue's bound is 1 mm and 0.01 degrees); the yaw, slerped about one axis,
    is exact but for rounding."""
    motion = PlanarMotion(speed_mps=10.0, yaw_rate_deg_s=30.0)
    rows_t = np.arange(1001) / 1000
    at_rows = motion.poses(rows_t).translation_m
    text = "".join(
        f"{t!r} {x!r} {y!r} {z!r} 0 0 {30.0 * t!r}\n"
        for t, (x, y, z) in zip(rows_t.tolist(), at_rows.tolist())
    )
    drive = load_trajectory(write(tmp_path, text))
    times = np.linspace(0.0, 1.0, 9973)
    got, want = drive.poses(times), motion.poses(times)
    sagitta_m = (10.0 / math.radians(30.0)) * (math.radians(30.0) * 1e-3) ** 2 / 8
    position_error_m = np.linalg.norm(got.translation_m - want.translation_m, axis=-1).max()
    assert 0.5 * sagitta_m < position_error_m <= 1.01 * sagitta_m < 1e-3
    # the angle between two rotations: |Ra - Rb| (Frobenius) = 2 sqrt(2) sin(angle / 2)
    angle_rad = np.linalg.norm(got.rotation - want.rotation, axis=(-2, -1)).max() / math.sqrt(2)
    assert angle_rad < 1e-12 < math.radians(0.01)


def test_commas_tabs_comments_blank_lines_and_crlf_read_as_spaces(tmp_path):
    plain = load_trajectory(write(tmp_path, "0 0 0 0 0 0 0\n1 10 0 0 0 0 90\n", "plain.txt"))
    written = (
        "# t, x, y, z, roll, pitch, yaw: a HELIOS++-like trajectory\r\n"
        "\r\n"
        "0,0,0,0,0,0,0   # the start\r\n"
        "   \t \r\n"
        "1.0 ,\t10.0, +0 , 0.0e0,0,-0.0,  9.0E1\r\n"
        "# the end"
    )
    same = load_trajectory(write(tmp_path, written, "written.csv"))
    times = np.linspace(0, 1, 7)
    assert np.array_equal(same.poses(times).rotation, plain.poses(times).rotation)
    assert np.array_equal(same.poses(times).translation_m, plain.poses(times).translation_m)


def test_an_angle_just_under_180_degrees_from_the_last_row_is_taken(tmp_path):
    drive = load_trajectory(write(tmp_path, "0 0 0 0 0 0 0\n1 0 0 0 0 0 179.9\n"))
    np.testing.assert_allclose(drive.poses(0.5).rotation, yaw_rotation(89.95), atol=1e-15)


ROWS = "0 0 0 0 0 0 0\n1 1 0 0 0 0 10\n"
# (file text, the line named, what the message says)
BAD_FILES = [
    ("", None, "expected at least 2 pose rows (t x y z roll pitch yaw (seconds, metres, "),
    ("# only a comment\n0 0 0 0 0 0 0\n", None, "expected at least 2 pose rows (t x y z"),
    (ROWS + "2 2 0 0 0 0\n", 3, "6 values, expected 7: t x y z roll pitch yaw"),
    (ROWS + "2,2,0,0,0,0,20,\n", 3, "8 values, expected 7"),
    ("t x y z roll pitch yaw\n" + ROWS, 1, "t 't': expected a finite decimal number"),
    (ROWS + "2 nan 0 0 0 0 20\n", 3, "x 'nan': expected a finite decimal number"),
    (ROWS + "2 2 inf 0 0 0 20\n", 3, "y 'inf': expected a finite decimal number"),
    (ROWS + "2 2 0 -Infinity 0 0 20\n", 3, "z '-Infinity': expected a finite"),
    (ROWS + "2 2 0 0 1e400 0 20\n", 3, "roll '1e400': expected a finite decimal number"),
    (ROWS + "2 2 0 0 0 0x10 20\n", 3, "pitch '0x10': expected a finite decimal number"),
    (ROWS + "2 2 0 0 0 0 1_000\n", 3, "yaw '1_000': expected a finite decimal number"),
    (ROWS + "2 2 0 0 0 0 \u0661\u0660\n", 3, "yaw '\u0661\u0660': expected a finite decimal"),
    (ROWS + "2,2,,0,0,0,20\n", 3, "y '': expected a finite decimal number"),
    (ROWS + "2 2 0 0\u00a00 0 20\n", 3, "6 values, expected 7"),  # no-break space: no separator
    (ROWS + "1 2 0 0 0 0 20\n", 3, "t 1.0 s after 1.0 s on line 2: expected times that strictly"),
    (ROWS + "\n\n0.5 2 0 0 0 0 20\n", 5, "t 0.5 s after 1.0 s on line 2"),
    ("0 0 0 0 0 0 0\n1e10 1 0 0 0 0 0\n", 2, "t 10000000000.0 s: expected seconds within"),
    (ROWS + "2 0 1000.5 0 0 0 0\n", 3, "y 1000.5 m: expected metres within +-1000 of the"),
    ("0 512345.6 5403210.2 0 0 0 0\n1 0 0 0 0 0 0\n", 1, "x 512345.6 m: expected metres"),
    (ROWS + "2 0 0 -1500 0 0 0\n", 3, "z -1500.0 m"),
    (
        "0 0 0 0 0 0 170\n1 0 0 0 0 0 -170\n",
        2,
        "yaw -170.0 after 170.0 on line 1: expected consecutive rows less than 180 degrees "
        "apart (slerp turns the short way; write angles unwrapped, 190 after 170)",
    ),
    ("0 0 0 0 0 0 0\n1 0 0 0 0 0 180\n", 2, "yaw 180.0 after 0.0 on line 1"),
    (ROWS + "2 0 0 0 200 0 10\n", 3, "roll 200.0 after 0.0 on line 2"),
    (ROWS + "2 0 0 0 0 -185 10\n", 3, "pitch -185.0 after 0.0 on line 2"),
    (ROWS + "2 0 0 0 0 0 " + "1" * 1_000_000 + "x\n", 3, "... (1000003 characters): expected"),
]


@pytest.mark.parametrize(("text", "line", "says"), BAD_FILES)
def test_a_bad_file_is_refused_in_one_line_naming_the_line(tmp_path, text, line, says):
    path = write(tmp_path, text)
    message = refusal(path)
    where = f"{path} line {line}: " if line else f"{path}: "
    assert message.startswith(where) and says in message, message


def test_too_many_rows_are_refused_at_the_first_row_past_the_limit(tmp_path, monkeypatch):
    monkeypatch.setattr(trajectory, "MAX_TRAJECTORY_ROWS", 3)
    rows = "# four rows\n" + "".join(f"{t} 0 0 0 0 0 0\n" for t in range(4))
    path = write(tmp_path, rows)
    assert refusal(path) == f"{path} line 5: expected at most 3 pose rows"
    path = write(tmp_path, rows[: rows.rindex("3 0")])  # three rows: taken
    assert len(load_trajectory(path).t_s) == 3


def test_errors_start_with_the_name_the_caller_gives(tmp_path):
    path = write(tmp_path, "0 0 0 0 0 0 0\n")
    message = refusal(path, where="--trajectory drive.txt")
    assert message.startswith("--trajectory drive.txt: expected at least 2 pose rows")


def test_a_named_pipe_is_refused_without_opening_it(tmp_path):
    path = tmp_path / "drive.txt"
    os.mkfifo(path)  # opening it would wait for a writer for ever
    assert refusal(path) == f"{path}: expected a regular file, got a named pipe"


def test_a_file_too_large_is_refused_before_it_is_parsed(tmp_path):
    path = tmp_path / "drive.txt"
    with path.open("wb") as f:  # sparse: no disk used
        f.truncate(MAX_TRAJECTORY_BYTES + 1)
    assert refusal(path) == (
        f"{path}: expected a file of at most {MAX_TRAJECTORY_BYTES} bytes, "
        f"got {MAX_TRAJECTORY_BYTES + 1} bytes"
    )


@pytest.mark.parametrize(
    ("make", "says"),
    [
        (lambda p: p.mkdir(), "expected a regular file, got a folder"),
        (lambda p: None, "file not found"),
        (lambda p: p.write_bytes(b"0 0 0 0 0 0 0\n\xff"), "expected UTF-8 text, got byte 0xff"),
    ],
)
def test_what_is_not_a_text_file_is_refused(tmp_path, make, says):
    path = tmp_path / "drive.txt"
    make(path)
    assert refusal(path).startswith(f"{path}: {says}")


def test_poses_outside_the_rows_times_are_refused(tmp_path):
    path = write(tmp_path, "0 0 0 0 0 0 0\n1 10 0 0 0 0 90\n")
    drive = load_trajectory(path)
    covered = f"{path}: poses from 0.0 s to 1.0 s, expected them to cover the simulated span"
    for times in (np.array([0.5, 1.5]), -0.001, np.array([[0.2, math.nan]])):
        with pytest.raises(ConfigError, match="^" + covered):
            drive.poses(times)
    assert drive.poses(np.zeros((0, 16))).rotation.shape == (0, 16, 3, 3)


def test_check_covers_names_both_spans(tmp_path):
    path = write(tmp_path, "0 0 0 0 0 0 0\n0.25 1 0 0 0 0 0\n")
    drive = load_trajectory(path)
    drive.check_covers(0.0, 0.25)
    with pytest.raises(ConfigError) as caught:
        drive.check_covers(0.0, 0.3)
    assert str(caught.value) == (
        f"{path}: poses from 0.0 s to 0.25 s, expected them to cover the simulated span "
        "0.0 s to 0.3 s"
    )
    with pytest.raises(ConfigError, match="^--trajectory: poses from 0.0 s"):
        drive.check_covers(-0.1, 0.2, "--trajectory")


@pytest.mark.parametrize(
    ("fields", "says"),
    [
        (dict(t_s=[0.0]), "arrays of shapes ((1,), (2, 3), (2, 4)), expected (K,), (K, 3)"),
        (dict(t_s=[1.0, 0.0]), "t_s: expected times that strictly increase"),
        (dict(t_s=[0.0, math.nan]), "t_s: expected finite numbers"),
        (dict(positions_m=np.zeros((2, 2))), "arrays of shapes ((2,), (2, 2), (2, 4))"),
        (dict(quaternions=np.zeros((2, 4))), "quaternions: expected unit quaternions"),
    ],
)
def test_a_trajectory_made_in_code_is_checked_too(fields, says):
    given_fields = dict(t_s=[0.0, 1.0], positions_m=np.zeros((2, 3)), quaternions=np.eye(2, 4))
    with pytest.raises(ConfigError, match=f"^drive: {re.escape(says)}"):
        Trajectory(**(given_fields | fields), source="drive")


def test_the_poses_are_the_trajectorys_own(tmp_path):
    t = np.array([0.0, 1.0])
    drive = Trajectory(t, np.zeros((2, 3)), np.eye(2, 4))
    t[1] = 5.0  # the caller's array changes; the trajectory does not
    assert drive.t_s.tolist() == [0.0, 1.0] and not drive.t_s.flags.writeable


steps = st.tuples(
    st.floats(0.001, 1.0),  # seconds to the next row
    *[st.floats(-50.0, 50.0)] * 3,  # metres
    *[st.floats(-179.0, 179.0)] * 3,  # degrees turned since the row before
)


@settings(max_examples=50, deadline=None)
@given(st.lists(steps, min_size=2, max_size=8), st.lists(st.floats(0.0, 1.0), max_size=20))
def test_interpolated_rotations_are_rotations_and_positions_lie_between_rows(rows, fractions):
    values = np.cumsum(np.array(rows), axis=0)
    values[:, 1:4] = np.array(rows)[:, 1:4]
    drive = Trajectory(values[:, 0], values[:, 1:4], quaternion_from_rpy(*values[:, 4:].T))
    times = values[0, 0] + np.array(fractions) * (values[-1, 0] - values[0, 0])
    poses = drive.poses(times)
    r = poses.rotation
    np.testing.assert_allclose(
        r @ np.swapaxes(r, -1, -2), np.broadcast_to(np.eye(3), r.shape), atol=1e-14
    )
    np.testing.assert_allclose(np.linalg.det(r), 1.0, atol=1e-14)
    k = np.clip(np.searchsorted(values[:, 0], times, side="right") - 1, 0, len(rows) - 2)
    low = np.minimum(values[k, 1:4], values[k + 1, 1:4])
    high = np.maximum(values[k, 1:4], values[k + 1, 1:4])
    assert ((low - 1e-12 <= poses.translation_m) & (poses.translation_m <= high + 1e-12)).all()
