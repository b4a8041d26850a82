"""Rotations as unit quaternions: built from roll, pitch and yaw, turned into matrices, and
interpolated by slerp.

A quaternion is stored (w, x, y, z), w the scalar part; ``q`` and ``-q`` are the same rotation.
Roll, pitch and yaw are the ZYX (intrinsic) angles of ROS (REP 103; ``tf2``'s ``setRPY``), in
the scene frame's axes (x forward, y left, z up):

    R = Rz(yaw) Ry(pitch) Rx(roll)

yaw turns counter-clockwise seen from above (x towards y), roll turns about x (forward) taking
y towards z, so a positive roll lifts the left side; pitch turns about y (left) taking z
towards x, so with y to the left a positive pitch tilts the nose DOWN (x towards -z).
"""

import numpy as np

# The half-angle between two quaternions (radians) under which slerp is replaced by linear
# interpolation: slerp's sin(f a) / sin(a) is 0 / 0 at a = 0, and at a = 1e-6 rad (a turn of
# 1.1e-4 degrees between two poses) the linear path strays from the arc by less than a^3 / 8 =
# 1e-19 rad, far below float64's 1.1e-16.
SLERP_MIN_ANGLE = 1e-6


def quaternion_from_rpy(roll_deg, pitch_deg, yaw_deg) -> np.ndarray:
    """The unit quaternions of ``Rz(yaw) Ry(pitch) Rx(roll)`` (module docstring): three
    broadcastable arrays of shape (*S,) in degrees -> (*S, 4) (w, x, y, z)."""
    half = np.deg2rad(np.stack(np.broadcast_arrays(roll_deg, pitch_deg, yaw_deg)).astype(float)) / 2
    (cr, cp, cy), (sr, sp, sy) = np.cos(half), np.sin(half)  # each (*S,)
    # the product qz(yaw) qy(pitch) qx(roll) of the three turns' quaternions, written out
    return np.stack(
        [
            cy * cp * cr + sy * sp * sr,
            cy * cp * sr - sy * sp * cr,
            cy * sp * cr + sy * cp * sr,
            sy * cp * cr - cy * sp * sr,
        ],
        axis=-1,
    )


def rotation_from_quaternion(q) -> np.ndarray:
    """The rotation matrices of quaternions (*S, 4) (w, x, y, z) -> (*S, 3, 3). A quaternion
    need not have length 1 (its rotation is that of ``q / |q|``; :func:`slerp`'s linear branch
    returns such), only not 0; ``q`` and ``-q`` give the same matrix, bit for bit."""
    q = np.asarray(q, dtype=np.float64)
    # contiguous components, and the nine entries stacked last: a third faster than writing
    # them into a (*S, 3, 3) array one strided entry at a time (463,000 pulses: 80 against
    # 103 ms)
    w, x, y, z = np.ascontiguousarray(np.moveaxis(q, -1, 0))  # each (*S,)
    s = 2.0 / (w * w + x * x + y * y + z * z)  # 2 / |q|^2: 2 for a unit quaternion
    xs, ys, zs = x * s, y * s, z * s
    entries = [
        [1.0 - (y * ys + z * zs), x * ys - w * zs, x * zs + w * ys],
        [x * ys + w * zs, 1.0 - (x * xs + z * zs), y * zs - w * xs],
        [x * zs - w * ys, y * zs + w * xs, 1.0 - (x * xs + y * ys)],
    ]
    return np.stack([e for row in entries for e in row], axis=-1).reshape(q.shape[:-1] + (3, 3))


def shorter_arc(q0, q1) -> tuple[np.ndarray, np.ndarray]:
    """The arc :func:`slerp` takes from unit quaternions ``q0`` to ``q1`` (each (*S, 4)): ``q1``
    or ``-q1``, whichever is nearer ``q0`` (the same rotation, the shorter way round), and the
    angle between the two as 4-vectors (*S,) radians, half the turn."""
    q0 = np.asarray(q0, dtype=np.float64)
    q1 = np.asarray(q1, dtype=np.float64)
    q1 = np.where(np.sum(q0 * q1, axis=-1, keepdims=True) < 0.0, -q1, q1)
    # from the chord's halves, 2 sin(a / 2) and 2 cos(a / 2): exact near 0, where
    # arccos(q0 . q1) loses half the digits
    angle = 2.0 * np.arctan2(np.linalg.norm(q0 - q1, axis=-1), np.linalg.norm(q0 + q1, axis=-1))
    return q1, angle


def slerp_on_arc(q0, q1, angle, fraction) -> np.ndarray:
    """:func:`slerp` from ``q0`` to ``q1`` (each (*S, 4)), ``angle`` (*S,) apart, as
    :func:`shorter_arc` gives them (a trajectory computes its rows' arcs once): (*S, 4)."""
    f = np.asarray(fraction, dtype=np.float64)
    tiny = angle < SLERP_MIN_ANGLE
    sin_angle = np.where(tiny, 1.0, np.sin(angle))
    w0 = np.where(tiny, 1.0 - f, np.sin((1.0 - f) * angle) / sin_angle)  # (*S,)
    w1 = np.where(tiny, f, np.sin(f * angle) / sin_angle)
    return w0[..., None] * q0 + w1[..., None] * q1


def slerp(q0, q1, fraction) -> np.ndarray:
    """Quaternions a ``fraction`` (*S,) of the way from unit quaternions ``q0`` to ``q1``
    (each (*S, 4)) along the shorter arc, turning at a constant rate: (*S, 4). ``q1`` is taken
    as ``-q1`` where ``q0 . q1 < 0``; below :data:`SLERP_MIN_ANGLE` the quaternions are
    interpolated linearly (and the result is then not of length 1). Fraction 0 gives ``q0``
    and fraction 1 ``+-q1``, both exactly."""
    q0 = np.asarray(q0, dtype=np.float64)
    q1, angle = shorter_arc(q0, q1)
    return slerp_on_arc(q0, q1, angle, fraction)
