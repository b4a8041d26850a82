"""How a surface's return falls with the incidence angle, per material (issue 62, item 3).

A spinning LiDAR is monostatic: it sees every surface in exact backscatter, the view direction
the illumination's. The range equation's ``rho cos(theta)`` (Lambert) becomes ``rho f(theta)``,
with ``rho`` the material's reflectance at normal incidence (what a datasheet's "pavement
(~0.10 reflectivity)" means) and f(0) = 1 for the diffuse part:

* ``lambert``: f = cos(theta).
* ``oren_nayar``: a rough diffuse surface of V-cavities whose slopes have the standard deviation
  sigma (``roughness_deg``). Oren & Nayar's qualitative model (SIGGRAPH 1994, eq. 30),
  ``L = (rho / pi) E cos(theta_i) (A + B max(0, cos(phi_r - phi_i)) sin(alpha) tan(beta))``,
  ``A = 1 - 0.5 sigma^2 / (sigma^2 + 0.33)``, ``B = 0.45 sigma^2 / (sigma^2 + 0.09)``, in
  backscatter (theta_i = theta_r = alpha = beta = theta, phi_r = phi_i) and divided by its
  value at normal incidence (A), is f = cos(theta) + (B / A) sin^2(theta): a rough surface
  stays bright at grazing incidence (the facets facing the sensor are lit and seen), up to
  0.9 of its normal-incidence return for the roughest. sigma = 0 is Lambert.
* a specular lobe on top (``specular`` rho_s, ``lobe_deg`` a), for a glossy coat (car paint's
  clear coat): Ward's isotropic Gaussian model (SIGGRAPH 1992),
  ``rho_s exp(-tan^2(delta) / a^2) / (4 pi a^2 sqrt(cos(theta_i) cos(theta_r)))``, in
  backscatter (the half vector is the view, delta = theta). A target's power follows pi BRDF
  cos(theta) (Lambert's rho / pi gives rho cos(theta)), so the coat adds rho_s f_s, f_s =
  exp(-tan^2(theta) / a^2) / (4 a^2), to the diffuse part's rho f.
* ``retroreflective``: a retro-reflector's gain falls with its entrance angle as cos^n(theta)
  (``exponent`` n): the coefficient of retroreflection of sheeting at entrance angle +30
  degrees against -4 degrees (ASTM D4956's table) sets n.
"""

import math

import numpy as np

ANGLE_LAWS = ("lambert", "oren_nayar", "retroreflective")


def oren_nayar_ratio(roughness_deg: float) -> float:
    """B / A of Oren & Nayar's qualitative model for facet slopes of sigma = ``roughness_deg``."""
    s2 = math.radians(roughness_deg) ** 2
    a = 1.0 - 0.5 * s2 / (s2 + 0.33)
    b = 0.45 * s2 / (s2 + 0.09)
    return b / a


def law_factor(cos_incidence, ratio=0.0, exponent=1.0):
    """f(theta) = cos^n(theta) + r sin^2(theta), the one form of every law here: Lambert (r =
    0, n = 1), Oren-Nayar (r = B / A, n = 1), retro-reflective (r = 0, n); 0 where cos(theta)
    <= 0 (seen from behind). Arguments broadcast (float64)."""
    c = np.clip(np.asarray(cos_incidence, dtype=np.float64), 0.0, 1.0)
    f = c**exponent + ratio * (1.0 - c**2)
    return np.where(c > 0.0, f, 0.0)


def angle_factor(law: str, cos_incidence, roughness_deg: float = 0.0, exponent: float = 1.0):
    """f(theta) of a surface's diffuse (or retro-reflective) part: its return at incidence theta
    over its return at normal incidence, of ``cos_incidence``'s shape (float64); cos(theta) is
    clipped to [0, 1] (a surface seen from behind returns nothing).

    law : of ``ANGLE_LAWS``; roughness_deg : sigma of ``oren_nayar`` (degrees); exponent : n of
    ``retroreflective``
    """
    if law == "lambert":
        return law_factor(cos_incidence)
    if law == "oren_nayar":
        return law_factor(cos_incidence, oren_nayar_ratio(roughness_deg))
    if law == "retroreflective":
        return law_factor(cos_incidence, 0.0, exponent)
    raise ValueError(f"law={law!r}: expected one of {list(ANGLE_LAWS)}")


def specular_factor(cos_incidence, lobe_deg):
    """f_s(theta) of a glossy coat's Ward lobe of width a = ``lobe_deg`` (> 0), per unit rho_s:
    the coat adds rho_s f_s to the surface's rho f (see the module), exp(-tan^2(theta) / a^2) /
    (4 a^2); the arguments' broadcast shape."""
    c = np.clip(np.asarray(cos_incidence, dtype=np.float64), 0.0, 1.0)
    a = np.radians(np.asarray(lobe_deg, dtype=np.float64))
    if not np.all(a > 0.0):
        raise ValueError(f"lobe_deg={lobe_deg!r}: expected a positive width")
    with np.errstate(divide="ignore"):
        tan2 = np.where(c > 0.0, (1.0 - c**2) / c**2, np.inf)
    return np.exp(-tan2 / a**2) / (4.0 * a**2)


def retro_exponent(ratio: float, entrance_deg: float) -> float:
    """n such that cos^n(entrance) = ``ratio`` (a retro-reflector's gain at that entrance angle
    over its gain near normal incidence)."""
    return math.log(ratio) / math.log(math.cos(math.radians(entrance_deg)))
