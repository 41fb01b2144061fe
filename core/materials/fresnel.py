"""Fresnel reflectance: exact unpolarised dielectric Fresnel, Schlick's approximation, and the
IOR mappings Blender's Principled BSDF uses.

Conventions: ``eta`` is the material's relative index of refraction, interior over exterior
(glass in air: 1.5). A cosine is measured against the normal that points to the exterior, so a
negative cosine means the light arrives from the interior and the ratio is inverted.
"""

from __future__ import annotations

import numpy as np

# Largest F0 the IOR mappings accept: F0 -> 1 means an infinite index.
_F0_MAX = 1.0 - 1e-9


def fresnel_dielectric(cos_i, eta):
    """Unpolarised Fresnel reflectance of a smooth dielectric interface.

    Parameters
    ----------
    cos_i : (k,) float
        Cosine between the incident direction (pointing away from the surface) and the
        exterior-facing normal; negative from the interior.
    eta : (k,) float
        Interior over exterior index (> 0).

    Returns
    -------
    (k,) float64 in [0, 1]
        1 under total internal reflection and at exact grazing incidence; 0 for ``eta == 1``
        (an index-matched interface does not reflect, even at grazing incidence).
    """
    cos_i = np.clip(np.asarray(cos_i, np.float64), -1.0, 1.0)
    eta = np.asarray(eta, np.float64)
    etap = np.where(cos_i < 0.0, 1.0 / eta, eta)
    ci = np.abs(cos_i)
    sin2_t = np.maximum(0.0, 1.0 - ci * ci) / (etap * etap)
    tir = sin2_t >= 1.0
    ct = np.sqrt(np.maximum(0.0, 1.0 - sin2_t))
    # Both denominators vanish only at exact grazing incidence (ci = ct = 0), where F = 1.
    den_s = ci + etap * ct
    den_p = etap * ci + ct
    ok = (den_s > 0.0) & (den_p > 0.0)
    rs = (ci - etap * ct) / np.where(ok, den_s, 1.0)
    rp = (etap * ci - ct) / np.where(ok, den_p, 1.0)
    f = np.where(ok, 0.5 * (rs * rs + rp * rp), 1.0)
    f = np.where(tir, 1.0, f)
    return np.where(eta == 1.0, 0.0, np.clip(f, 0.0, 1.0))


def fresnel_schlick(f0, cos_i):
    """Schlick's approximation ``F0 + (1 - F0) (1 - cos)^5`` with a colour ``F0``.

    Parameters
    ----------
    f0 : (k, 3) float
        Reflectance at normal incidence.
    cos_i : (k,) float
        Cosine of the incident angle; its absolute value is used.

    Returns
    -------
    (k, 3) float64
    """
    c = 1.0 - np.clip(np.abs(cos_i), 0.0, 1.0)
    c2 = c * c
    return f0 + (1.0 - f0) * (c2 * c2 * c)[:, None]


def f0_from_ior(eta):
    """Normal-incidence reflectance ``((eta - 1) / (eta + 1))^2`` of an interface."""
    eta = np.asarray(eta, np.float64)
    return ((eta - 1.0) / (eta + 1.0)) ** 2


def ior_from_f0(f0):
    """Index (>= 1) whose normal-incidence reflectance is ``f0`` (inverse of ``f0_from_ior``)."""
    s = np.sqrt(np.clip(np.asarray(f0, np.float64), 0.0, _F0_MAX))
    return (1.0 + s) / (1.0 - s)


def adjust_ior_for_specular_level(ior, specular_ior_level):
    """Principled BSDF's *Specular IOR Level*: scale F0 by ``2 level`` and map back to an IOR.

    0.5 leaves the IOR unchanged, 0 removes the reflection (IOR 1), 1 doubles the reflectance at
    normal incidence (Blender 4 manual). Indices below one are treated by their reciprocal.

    Parameters
    ----------
    ior, specular_ior_level : (k,) float

    Returns
    -------
    (k,) float64 >= 1
    """
    ior = np.asarray(ior, np.float64)
    ior = np.where(ior < 1.0, 1.0 / np.maximum(ior, 1e-6), ior)
    level = np.clip(np.asarray(specular_ior_level, np.float64), 0.0, 1.0)
    return ior_from_f0(f0_from_ior(ior) * 2.0 * level)
