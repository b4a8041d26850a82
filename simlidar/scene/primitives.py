"""Unit templates of the recipe primitives, as triangle arrays.

Each template sits on its own origin: x and y in [-0.5, 0.5], z in [0, 1] (so a primitive's
``at`` is its bottom centre and ``size`` its extent along x, y, z before yaw). Closed solids wind
their triangles so that the normal ``(v1 - v0) x (v2 - v0)`` points outward; the ray caster uses
that to drop faces a sensor outside the solid can never hit first.
"""

from dataclasses import dataclass
from functools import cache

import numpy as np


@dataclass(frozen=True)
class Template:
    triangles: np.ndarray  # (T, 3, 3) float64, unit shape
    closed: bool  # a closed solid with outward winding (back faces may be culled)


def _orient_outward(triangles: np.ndarray, inside: np.ndarray) -> np.ndarray:
    """Flip the triangles of a convex solid whose normal points towards ``inside``."""
    normals = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    inward = np.einsum("ij,ij->i", normals, triangles.mean(axis=1) - inside) < 0
    triangles = triangles.copy()
    triangles[inward] = triangles[inward][:, ::-1]
    return triangles


def _quads(corners: np.ndarray) -> np.ndarray:
    """(Q, 4, 3) quads with corners in cyclic order -> (2Q, 3, 3) triangles."""
    return np.concatenate([corners[:, [0, 1, 2]], corners[:, [0, 2, 3]]])


@cache
def box() -> Template:
    """The unit box [-0.5, 0.5] x [-0.5, 0.5] x [0, 1]: 12 triangles."""
    c = np.array(
        [[x, y, z] for z in (0.0, 1.0) for y in (-0.5, 0.5) for x in (-0.5, 0.5)]
    )  # corner k = x + 2y + 4z (bits)
    faces = np.array(
        [[0, 1, 3, 2], [4, 5, 7, 6], [0, 1, 5, 4], [2, 3, 7, 6], [0, 2, 6, 4], [1, 3, 7, 5]]
    )
    return Template(_orient_outward(_quads(c[faces]), np.array([0.0, 0.0, 0.5])), closed=True)


@cache
def cylinder(segments: int) -> Template:
    """A capped vertical cylinder of diameter 1 and height 1 with ``segments`` sides."""
    theta = np.linspace(0.0, 2.0 * np.pi, segments, endpoint=False)
    ring = np.stack([0.5 * np.cos(theta), 0.5 * np.sin(theta)], axis=1)  # (S, 2)
    nxt = np.roll(ring, -1, axis=0)
    z0, z1 = np.zeros((segments, 1)), np.ones((segments, 1))
    sides = np.stack(
        [np.hstack([ring, z0]), np.hstack([nxt, z0]), np.hstack([nxt, z1]), np.hstack([ring, z1])],
        axis=1,
    )
    fan = np.arange(1, segments - 1)
    caps = [
        np.stack(
            [
                np.broadcast_to(np.append(ring[0], z), (len(fan), 3)),
                np.hstack([ring[fan], np.full((len(fan), 1), z)]),
                np.hstack([ring[fan + 1], np.full((len(fan), 1), z)]),
            ],
            axis=1,
        )
        for z in (0.0, 1.0)
    ]
    triangles = np.concatenate([_quads(sides), *caps])
    return Template(_orient_outward(triangles, np.array([0.0, 0.0, 0.5])), closed=True)


@cache
def arch(segments: int) -> Template:
    """A half-elliptic shell along x: span 1 in y, rise 1 in z, length 1; open, two-sided."""
    theta = np.linspace(0.0, np.pi, segments + 1)
    profile = np.stack([0.5 * np.cos(theta), np.sin(theta)], axis=1)  # (S+1, 2) in (y, z)
    a, b = profile[:-1], profile[1:]
    quads = np.stack(
        [
            np.column_stack([np.full(segments, x), p[:, 0], p[:, 1]])
            for x, p in ((-0.5, a), (-0.5, b), (0.5, b), (0.5, a))
        ],
        axis=1,
    )
    return Template(_quads(quads), closed=False)


KINDS = {"box": box, "cylinder": cylinder, "arch": arch}
DEFAULT_SEGMENTS = {"box": 0, "cylinder": 8, "arch": 12}


def template(kind: str, segments: int) -> Template:
    """The template of a primitive kind (``segments`` is ignored for boxes)."""
    return box() if kind == "box" else KINDS[kind](segments)
