"""Rigid poses and the planar motion, against numbers derived by hand."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from simlidar.motion.poses import PlanarMotion, Poses, yaw_rotation


def test_a_straight_drive_is_speed_times_time():
    poses = PlanarMotion(speed_mps=10.0).poses(np.array([0.0, 0.05, 0.1]))
    np.testing.assert_allclose(poses.translation_m[:, 0], [0.0, 0.5, 1.0], atol=1e-15)
    assert (poses.translation_m[:, 1:] == 0.0).all()
    np.testing.assert_array_equal(poses.rotation, np.broadcast_to(np.eye(3), (3, 3, 3)))


def test_a_quarter_circle_by_hand():
    """10 m/s turning at 90 deg/s for 1 s: a quarter circle of radius v / w = 20 / pi m, so the
    car ends at (R, R) facing +y (left)."""
    radius = 10.0 / (math.pi / 2)
    poses = PlanarMotion(speed_mps=10.0, yaw_rate_deg_s=90.0).poses(1.0)
    np.testing.assert_allclose(poses.translation_m, [radius, radius, 0.0], atol=1e-12)
    np.testing.assert_allclose(poses.rotation, [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-15)
    # the point 1 m ahead of the car is then 1 m to its left of the centre, in the scene
    np.testing.assert_allclose(poses.to_scene(np.array([1.0, 0, 0])), [radius, radius + 1, 0])


def test_the_chord_agrees_with_the_circle_at_any_yaw_rate():
    t = np.linspace(0.0, 2.0, 201)
    for w_deg in (1e-9, 0.5, 30.0, -45.0, 400.0):
        w = math.radians(w_deg)
        heading = math.radians(20.0)
        got = PlanarMotion(7.0, w_deg, heading_deg=20.0).poses(t).translation_m
        along = np.sin(heading + w * t) - math.sin(heading)
        across = math.cos(heading) - np.cos(heading + w * t)
        circle = (7.0 / w) * np.stack([along, across], -1)
        # the circle's form loses digits to cancellation as w -> 0 (v / w times a difference)
        tolerance = 1e-9 if abs(w_deg) >= 0.5 else 1e-3
        np.testing.assert_allclose(got[:, :2], circle, atol=tolerance, err_msg=str(w_deg))


def test_an_object_turns_about_its_own_reference_point():
    motion = PlanarMotion(speed_mps=0.0, yaw_rate_deg_s=90.0, origin_m=(10.0, 2.0))
    poses = motion.poses(1.0)
    np.testing.assert_allclose(poses.to_scene(np.array([10.0, 2.0, 0.5])), [10.0, 2.0, 0.5])
    np.testing.assert_allclose(poses.to_scene(np.array([11.0, 2.0, 0.0])), [10.0, 3.0, 0.0])


def test_no_motion_is_the_identity_bit_for_bit():
    points = np.random.default_rng(0).normal(size=(4, 5, 3)) * 50
    poses = PlanarMotion().poses(np.zeros((4, 5)))
    assert not PlanarMotion().moves
    np.testing.assert_array_equal(poses.to_scene(points), points)
    np.testing.assert_array_equal(poses.to_body(points), points)


@given(
    st.floats(-30.0, 30.0), st.floats(-90.0, 90.0), st.floats(-180.0, 180.0), st.floats(0.0, 5.0)
)
def test_to_body_undoes_to_scene(speed, yaw_rate, heading, t):
    poses = PlanarMotion(speed, yaw_rate, heading, (3.0, -1.0)).poses(np.array([t]))
    x = np.array([[12.0, -4.0, 1.5]])
    np.testing.assert_allclose(poses.to_body(poses.to_scene(x)), x, atol=1e-9)
    r = poses.rotation[0]
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(r) == pytest.approx(1.0)


def test_relative_to_gives_the_pose_seen_from_a_reference():
    a = Poses(yaw_rotation(90.0), np.array([1.0, 2.0, 0.0]))
    b = Poses(yaw_rotation(0.0), np.array([5.0, 0.0, 0.0]))
    x = np.array([0.5, 0.25, 1.0])
    # a point of a's frame, seen from b's: b^-1 (a x)
    np.testing.assert_allclose(a.relative_to(b).to_scene(x), b.to_body(a.to_scene(x)))
