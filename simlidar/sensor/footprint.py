"""A pulse's beam as sub-rays over its divergence (issue 41; HELIOS++'s beam sampling).

A real beam is a cone, not a line: at 50 m a 3 mrad beam is 15 cm wide, and a beam across an
edge lights two surfaces at once. HELIOS++ (Winiwarter et al. 2022) samples the cone with
``beamSampleQuality`` Q rings of sub-rays: ring ``k`` (k = 0 .. Q-1) holds ``6 k`` sub-rays
(one, the central ray, for k = 0), evenly spaced around it, so a beam has ``1 + 3 Q (Q - 1)``
(Q = 1: 1, 2: 7, 3: 19; HELIOS++'s default ``beamSampleQuality`` is 3, its ``FWFSettings.h``),
and each sub-ray carries the power of a Gaussian beam profile at its offset,
``exp(-2 r^2 / w^2)`` (HELIOS++'s ``calcEmmitedPower``, after Carlsson et al. 2001).

Here (every choice listed in docs/sensor-model.md, "Beam footprint"):

* the receiver file's ``divergence_h_mrad`` / ``divergence_v_mrad`` are read as the full angles
  of the beam at its 1/e^2 irradiance (assumption: the VLS-128 manual, where they come from,
  does not say which width it quotes), so the beam is an ellipse with 1/e^2 half-angles
  ``a = divergence_h / 2`` along the scan and ``b = divergence_v / 2`` across it;
* ring ``k`` lies at the normalised radius ``rho_k = k * step``, ``step = 1 / (Q - 1/2)``, so the
  rings' cells (the central disc of radius step / 2, then annuli of width ``step``) tile the
  ellipse out to its 1/e^2 contour; a sub-ray at angle ``phi_j = 2 pi j / (6 k)`` on ring k points
  ``(a rho_k cos phi_j, b rho_k sin phi_j)`` off the beam's axis (horizontal, vertical);
* its weight is the Gaussian irradiance at its offset times its cell's area (pi step^2 / 4 for
  the central ray, pi step^2 / 3 for each ray of a ring), normalised to sum to 1: a target that
  fills the beam then returns the power of the range equation, whatever Q, so the receiver's
  calibration (its threshold, set for the central ray) holds for every footprint.

Q = 1 is one ray along the axis with weight 1: today's geometry.
"""

import math

import numpy as np

MAX_RINGS = 8  # 169 sub-rays a beam


def subray_count(rings: int) -> int:
    """Sub-rays a beam of ``rings`` rings: 1 + 3 Q (Q - 1)."""
    return 1 + 3 * rings * (rings - 1)


def footprint(rings: int) -> tuple[np.ndarray, np.ndarray]:
    """The sub-ray pattern of ``rings`` rings: offsets (S, 2) in units of the 1/e^2 half-angles
    (horizontal, vertical; the central ray first, at (0, 0)) and weights (S,) summing to 1."""
    if isinstance(rings, bool) or not isinstance(rings, int) or not 1 <= rings <= MAX_RINGS:
        raise ValueError(f"rings={rings!r}: expected an integer in [1, {MAX_RINGS}]")
    step = 1.0 / (rings - 0.5)
    offsets, areas = [(0.0, 0.0)], [math.pi * step**2 / 4.0]
    for k in range(1, rings):
        count = 6 * k
        for j in range(count):
            phi = 2.0 * math.pi * j / count
            offsets.append((k * step * math.cos(phi), k * step * math.sin(phi)))
            areas.append(math.pi * step**2 / 3.0)
    offsets = np.asarray(offsets)
    weights = np.exp(-2.0 * (offsets**2).sum(axis=1)) * np.asarray(areas)
    return offsets, weights / weights.sum()


def subray_directions(
    directions: np.ndarray, divergence_h_mrad: float, divergence_v_mrad: float, rings: int
) -> tuple[np.ndarray, np.ndarray]:
    """Every beam's sub-ray directions and the sub-rays' weights.

    directions : (..., 3) unit beam axes (not pointing straight up or down)
    returns : (..., S, 3) unit directions, sub-ray 0 the axis itself (the same float64 values),
        and weights (S,) (:func:`footprint`)
    """
    offsets, weights = footprint(rings)
    d = np.asarray(directions, dtype=np.float64)
    across = np.stack([-d[..., 1], d[..., 0], np.zeros_like(d[..., 0])], axis=-1)  # z x d
    across /= np.linalg.norm(across, axis=-1, keepdims=True)  # horizontal, along the scan
    up = np.cross(d, across)  # vertical, across the scan
    half_h = np.tan(0.5e-3 * divergence_h_mrad * offsets[:, 0])  # (S,)
    half_v = np.tan(0.5e-3 * divergence_v_mrad * offsets[:, 1])
    rays = (
        d[..., None, :]
        + half_h[:, None] * across[..., None, :]
        + half_v[:, None] * up[..., None, :]
    )
    rays /= np.linalg.norm(rays, axis=-1, keepdims=True)
    rays[..., 0, :] = d  # the axis exactly, as the single-ray model casts it
    return rays, weights
