"""Rigid poses and the motions that give one at any time.

A pose maps a body's own frame to the scene's: a point ``x`` of the body is ``R x + p`` in the
scene (``R`` a rotation, ``p`` a translation in metres). The scene frame is the sample's
(x forward along the road, y left, z up, road at z = 0; docs/scenes.md), so a body that does not
move has the identity pose. A *motion* gives the poses of a body at many times at once:
``motion.poses(t_s)`` for times of any shape (a frame's pulses, (B, H, C)), each pulse then
cast at its own time (:func:`simlidar.sensor.moving.cast_moving`).

:class:`PlanarMotion` is the motion of the ego vehicle and of the catalog's objects: a constant
speed along a heading that turns at a constant yaw rate (a unicycle, the constant-velocity model
KISS-ICP deskews with, restricted to the road's plane), in closed form: exact at every time,
with no time steps.
"""

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Poses:
    """Rigid poses of any leading shape S: a body's point ``x`` is ``rotation @ x +
    translation_m`` in the scene frame."""

    rotation: np.ndarray  # (*S, 3, 3) float64, orthonormal, determinant +1
    translation_m: np.ndarray  # (*S, 3) float64

    def to_scene(self, points: np.ndarray) -> np.ndarray:
        """Points of the body's frame in the scene frame: (*S, 3) -> (*S, 3)."""
        return self.rotate(points) + self.translation_m

    def to_body(self, points: np.ndarray) -> np.ndarray:
        """Points of the scene frame in the body's frame: (*S, 3) -> (*S, 3)."""
        return self.unrotate(points - self.translation_m)

    def rotate(self, vectors: np.ndarray) -> np.ndarray:
        """Directions of the body's frame in the scene frame: (*S, 3) -> (*S, 3)."""
        return np.einsum("...ij,...j->...i", self.rotation, vectors)

    def unrotate(self, vectors: np.ndarray) -> np.ndarray:
        """Directions of the scene frame in the body's frame: (*S, 3) -> (*S, 3)."""
        return np.einsum("...ji,...j->...i", self.rotation, vectors)

    def relative_to(self, reference: "Poses") -> "Poses":
        """These poses seen from ``reference``'s frame (a deskew's map from each pulse's sensor
        frame to the frame's reference pose): ``reference^-1 o self``, broadcast."""
        rotation = np.einsum("...ji,...jk->...ik", reference.rotation, self.rotation)
        return Poses(rotation, reference.to_body(self.translation_m))


def yaw_rotation(yaw_deg) -> np.ndarray:
    """Rotations about the vertical axis, counter-clockwise seen from above: (*S,) degrees ->
    (*S, 3, 3)."""
    yaw = np.deg2rad(np.asarray(yaw_deg, dtype=np.float64))
    return _about_z(np.cos(yaw), np.sin(yaw))


def _about_z(c: np.ndarray, s: np.ndarray) -> np.ndarray:
    """The rotations about z of cosines ``c`` and sines ``s`` (*S,): (*S, 3, 3)."""
    rotation = np.zeros(c.shape + (3, 3))
    rotation[..., 0, 0], rotation[..., 0, 1] = c, -s
    rotation[..., 1, 0], rotation[..., 1, 1] = s, c
    rotation[..., 2, 2] = 1.0
    return rotation


@dataclass(frozen=True)
class PlanarMotion:
    """A rigid body moving in the road's plane at a constant speed along a direction of travel
    that turns, with the body, at a constant yaw rate: from its pose at t = 0 (the scene as
    built), its reference point ``origin_m`` travels the arc

        d(t) = v t sinc(w t / 2) (cos(h + w t / 2), sin(h + w t / 2)),  sinc(x) = sin(x) / x

    (``h`` the heading of travel at t = 0, ``w`` the yaw rate; a straight line when w = 0) and
    the body turns by ``w t`` about the vertical through that point. The half-angle form is the
    chord of the arc, exact for every w and free of the 0 / 0 of ``v / w (sin(h + w t) -
    sin h)`` at small w."""

    speed_mps: float = 0.0
    yaw_rate_deg_s: float = 0.0
    heading_deg: float = 0.0  # direction of travel at t = 0, counter-clockwise from x
    origin_m: tuple[float, float] = (0.0, 0.0)  # the point the body turns about, at t = 0

    @property
    def moves(self) -> bool:
        return bool(np.any(self.speed_mps) or np.any(self.yaw_rate_deg_s))

    def poses(self, t_s) -> Poses:
        """The body's poses at times ``t_s`` (*S,) seconds from t = 0: (*S) poses mapping its
        frame at t = 0 (the scene as built) to the scene at each time. Each field may also be
        an array that broadcasts against ``t_s`` (a batch of bodies: (B, 1, 1) against a
        frame's (B, H, C) times; ``origin_m`` a pair of such arrays)."""
        t = np.asarray(t_s, dtype=np.float64)
        turn = np.deg2rad(self.yaw_rate_deg_s) * t  # (*S,) radians turned by then
        chord = self.speed_mps * t * np.sinc(turn / (2.0 * np.pi))  # np.sinc(x) = sin(pi x)/(pi x)
        along = np.deg2rad(self.heading_deg) + turn / 2.0
        c, s = np.cos(turn), np.sin(turn)
        ox, oy = (np.asarray(v, dtype=np.float64) for v in self.origin_m)
        rotation = _about_z(c, s)
        # a point x of the body at t = 0 goes to R (x - origin) + origin + d(t)
        translation = np.stack(
            np.broadcast_arrays(
                ox - (c * ox - s * oy) + chord * np.cos(along),
                oy - (s * ox + c * oy) + chord * np.sin(along),
                np.zeros_like(turn),
            ),
            axis=-1,
        )
        return Poses(rotation, translation)
