"""Quaternions from roll, pitch and yaw, their matrices and slerp, against matrices written by
hand for quarter turns and against poses.yaw_rotation."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from simlidar.motion.poses import yaw_rotation
from simlidar.motion.rotations import (
    SLERP_MIN_ANGLE,
    quaternion_from_rpy,
    rotation_from_quaternion,
    slerp,
)


def rotation(roll_deg, pitch_deg, yaw_deg):
    return rotation_from_quaternion(quaternion_from_rpy(roll_deg, pitch_deg, yaw_deg))


def test_yaw_alone_is_the_yaw_rotation_of_poses():
    yaw = np.linspace(-720.0, 720.0, 1441)
    np.testing.assert_allclose(rotation(0.0, 0.0, yaw), yaw_rotation(yaw), rtol=0, atol=1e-15)


# Each matrix by hand: its columns are where the body's forward (x), left (y) and up (z) axes
# point in the scene.
QUARTER_TURNS = [
    # yaw 90: forward -> left, left -> back
    ((0, 0, 90), [[0, -1, 0], [1, 0, 0], [0, 0, 1]]),
    # roll 90 about forward: left -> up, up -> right (the left side lifted)
    ((90, 0, 0), [[1, 0, 0], [0, 0, -1], [0, 1, 0]]),
    # pitch 90 about left: forward -> down (the nose down), up -> forward
    ((0, 90, 0), [[0, 0, 1], [0, 1, 0], [-1, 0, 0]]),
    # Rz(90) Rx(90): roll first (left -> up), then yaw (forward -> left, up stays up)
    ((90, 0, 90), [[0, 0, 1], [1, 0, 0], [0, 1, 0]]),
    # Ry(90) Rx(90): roll first (left -> up, up -> right), then pitch (up -> forward)
    ((90, 90, 0), [[0, 1, 0], [0, 0, -1], [-1, 0, 0]]),
]


@pytest.mark.parametrize(("rpy", "matrix"), QUARTER_TURNS)
def test_quarter_turns_by_hand(rpy, matrix):
    np.testing.assert_allclose(rotation(*rpy), matrix, rtol=0, atol=1e-15)


def test_the_order_is_yaw_of_pitch_of_roll_not_the_reverse():
    # Rx(90) Rz(90) would send forward to up; Rz(90) Rx(90) sends it to the left
    np.testing.assert_allclose(rotation(90, 0, 90) @ [1, 0, 0], [0, 1, 0], atol=1e-15)


def test_a_positive_pitch_tilts_the_nose_down():
    nose = rotation(0.0, 10.0, 0.0) @ [1.0, 0.0, 0.0]
    np.testing.assert_allclose(nose, [math.cos(math.radians(10)), 0, -math.sin(math.radians(10))])


angles = st.floats(-720.0, 720.0, allow_nan=False)


@settings(max_examples=200, deadline=None)
@given(angles, angles, angles)
def test_every_rotation_is_orthonormal_with_determinant_one(roll, pitch, yaw):
    q = quaternion_from_rpy(roll, pitch, yaw)
    assert abs(np.dot(q, q) - 1.0) < 1e-15
    r = rotation_from_quaternion(q)
    # to rounding: a few float64 steps (2.2e-16) over sums of products of entries
    np.testing.assert_allclose(r @ r.T, np.eye(3), rtol=0, atol=1e-14)
    assert abs(np.linalg.det(r) - 1.0) < 1e-14
    # q and -q are one rotation, to the bit
    assert np.array_equal(rotation_from_quaternion(-q), r)


def test_slerp_turns_at_a_constant_rate():
    fractions = np.linspace(0.0, 1.0, 11)
    q0, q1 = quaternion_from_rpy(0, 0, 0), quaternion_from_rpy(0, 0, 120)
    turned = rotation_from_quaternion(slerp(q0, q1, fractions))
    np.testing.assert_allclose(turned, yaw_rotation(120 * fractions), rtol=0, atol=1e-15)


def test_slerp_takes_the_short_way_when_the_dot_product_is_negative():
    """-q of a 90-degree yaw is the same rotation; the arc from the identity to it is the
    short one (45 degrees half way), not the long one through 180 (-135 half way)."""
    q0 = quaternion_from_rpy(0, 0, 0)
    q1 = -quaternion_from_rpy(0, 0, 90)
    assert np.dot(q0, q1) < 0
    halfway = rotation_from_quaternion(slerp(q0, q1, 0.5))
    np.testing.assert_allclose(halfway, yaw_rotation(45.0), rtol=0, atol=1e-15)
    # and at the ends, the two rotations exactly
    assert np.array_equal(slerp(q0, q1, 0.0), q0)
    assert np.array_equal(
        rotation_from_quaternion(slerp(q0, q1, 1.0)), rotation_from_quaternion(q1)
    )


@pytest.mark.parametrize("yaw_deg", [0.0, 1e-9, 1e-3])
def test_slerp_between_nearly_equal_rotations_has_no_zero_over_zero(yaw_deg):
    # 0 and 1e-9 degrees apart are below SLERP_MIN_ANGLE (half the turn, in radians: 1.1e-4
    # degrees), 1e-3 degrees above it
    q0, q1 = quaternion_from_rpy(0, 0, 30.0), quaternion_from_rpy(0, 0, 30.0 + yaw_deg)
    assert (math.radians(yaw_deg) / 2 < SLERP_MIN_ANGLE) == (yaw_deg < 1e-4)
    fractions = np.linspace(0.0, 1.0, 5)
    turned = rotation_from_quaternion(slerp(q0, q1, fractions))
    assert np.isfinite(turned).all()
    np.testing.assert_allclose(turned, yaw_rotation(30.0 + yaw_deg * fractions), rtol=0, atol=1e-15)
