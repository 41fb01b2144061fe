"""The GGX (Trowbridge-Reitz) microfacet distribution: D, Smith masking, visible-normal sampling.

Isotropic GGX in the local frame (+Z = macro normal), with Blender's roughness convention
``alpha = roughness^2`` (Cycles squares the Roughness socket).

- ``D(m) = alpha^2 / (pi (1 + (alpha^2 - 1) cos^2 theta_m)^2)`` for ``m.z > 0``, so that
  ``int D(m) cos theta_m dm = 1``.
- Smith masking ``G1(w) = 1 / (1 + Lambda(w))`` with
  ``Lambda = (sqrt(1 + alpha^2 tan^2 theta) - 1) / 2`` and the *height-correlated*
  masking-shadowing ``G2(wo, wi) = 1 / (1 + Lambda(wo) + Lambda(wi))`` (Heitz 2014; Cycles and
  pbrt-v4 use the same, also for transmission).
- Visible normals (Heitz 2018, "Sampling the GGX distribution of visible normals"), density
  ``D_wo(m) = G1(wo) max(0, wo.m) D(m) / |wo.z|`` per unit solid angle of ``m``.

Every term is written in a form that stays finite at grazing angles: with
``a(w) = sqrt(w.z^2 + alpha^2 (1 - w.z^2)) = |w.z| (1 + 2 Lambda(w))``,
``G1 = 2 |w.z| / (|w.z| + a)``, ``G2 = 2 |zo| |zi| / (a_o |zi| + a_i |zo|)``; nothing divides by a
cosine. Directions with ``w.z < 0`` (inside a dielectric) are handled by ``|w.z|``.

``alpha`` is clamped to ``ALPHA_MIN``; rows with ``alpha <= ALPHA_SMOOTH`` are *smooth*: the BSDF
families treat them as their delta (perfectly specular) variant, exactly as Cycles does
(``alpha_x * alpha_y <= 1e-7``, i.e. roughness below about 0.0178).
"""

from __future__ import annotations

import numpy as np

from ..sampling import warps

ALPHA_MIN = 1e-4
ALPHA_SMOOTH = float(np.sqrt(1e-7))


def alpha_from_roughness(roughness):
    """``alpha = clip(roughness, 0, 1)^2`` (Blender/Cycles), floored at ``ALPHA_MIN``. ``(k,)``."""
    r = np.clip(np.nan_to_num(np.asarray(roughness, np.float64)), 0.0, 1.0)
    return np.maximum(r * r, ALPHA_MIN)


def is_smooth(alpha):
    """Rows whose GGX lobe is treated as a delta (perfect specular) lobe. ``(k,)`` bool."""
    return np.asarray(alpha) <= ALPHA_SMOOTH


def _a(cos, alpha):
    """``sqrt(cos^2 + alpha^2 sin^2) = |cos| (1 + 2 Lambda)``, positive for ``alpha > 0``."""
    c2 = np.minimum(cos * cos, 1.0)
    return np.sqrt(c2 + alpha * alpha * (1.0 - c2))


def ggx_d(cos_m, alpha):
    """GGX normal distribution ``D(m)`` from ``cos_m = m.z``; zero for ``m.z <= 0``. ``(k,)``."""
    a2 = alpha * alpha
    c2 = np.minimum(cos_m * cos_m, 1.0)
    t = 1.0 + (a2 - 1.0) * c2
    return np.where(cos_m > 0.0, a2 / (np.pi * t * t), 0.0)


def ggx_projected_area(cos, alpha):
    """Projected area of the microsurface toward ``w``, ``int max(0, w.m) D(m) dm``.

    ``= |cos| (1 + Lambda(w)) = (|cos| + a(w)) / 2``, positive for ``alpha > 0`` even in the
    tangent plane (where it is ``alpha / 2``). ``(k,)``.
    """
    return 0.5 * (np.abs(cos) + _a(cos, alpha))


def ggx_lambda(cos, alpha):
    """Smith ``Lambda(w)`` from ``cos = w.z`` (``inf`` in the tangent plane). ``(k,)``.

    For reference and tests; the BSDFs use the finite forms below instead.
    """
    ac = np.abs(cos)
    return np.where(ac > 0.0, 0.5 * (_a(cos, alpha) / np.where(ac > 0.0, ac, 1.0) - 1.0), np.inf)


def ggx_g1(cos, alpha):
    """Smith masking ``G1(w) = 2 |w.z| / (|w.z| + a(w))`` in [0, 1]. ``(k,)``."""
    ac = np.abs(cos)
    return 2.0 * ac / (ac + _a(cos, alpha))


def ggx_g2(cos_o, cos_i, alpha):
    """Height-correlated ``G2 = 1 / (1 + Lambda_o + Lambda_i)`` in [0, 1]. ``(k,)``."""
    co, ci = np.abs(cos_o), np.abs(cos_i)
    den = _a(cos_o, alpha) * ci + _a(cos_i, alpha) * co
    return np.where(den > 0.0, 2.0 * co * ci / np.where(den > 0.0, den, 1.0), 0.0)


def ggx_g2_over_g1(cos_o, cos_i, alpha):
    """``G2(wo, wi) / G1(wo)``, the weight of a visible-normal sample, in [0, 1]. ``(k,)``."""
    co, ci = np.abs(cos_o), np.abs(cos_i)
    ao = _a(cos_o, alpha)
    den = ao * ci + _a(cos_i, alpha) * co
    return np.where(den > 0.0, (ao + co) * ci / np.where(den > 0.0, den, 1.0), 0.0)


def ggx_visibility(cos_o, cos_i, alpha):
    """``G2 / (4 |cos_o| |cos_i|) = 1 / (2 (a_o |cos_i| + a_i |cos_o|))``; zero if both vanish."""
    co, ci = np.abs(cos_o), np.abs(cos_i)
    den = _a(cos_o, alpha) * ci + _a(cos_i, alpha) * co
    return np.where(den > 0.0, 0.5 / np.where(den > 0.0, den, 1.0), 0.0)


def ggx_visible_pdf(wo, wm, alpha):
    """Density ``D_wo(m)`` of :func:`sample_ggx_visible` per unit solid angle of ``m``.

    ``D_wo(m) = G1(wo) max(0, wo'.m) D(m) / |wo.z| = max(0, wo'.m) D(m) / A(wo)`` with ``A`` the
    projected area (:func:`ggx_projected_area`),
    where ``wo' = wo`` if ``wo.z >= 0`` and ``-wo`` otherwise (the microsurface seen from below is
    the same distribution seen through the origin).

    Parameters
    ----------
    wo : (k, 3) float
    wm : (k, 3) float
        Unit microfacet normals.
    alpha : (k,) float

    Returns
    -------
    (k,) float64
    """
    side = np.where(wo[:, 2] >= 0.0, 1.0, -1.0)
    cos_om = np.maximum(0.0, side * np.einsum("ij,ij->i", wo, wm))
    return cos_om * ggx_d(wm[:, 2], alpha) / ggx_projected_area(wo[:, 2], alpha)


def sample_ggx_visible(wo, alpha, u, alpha_y=None):
    """Sample microfacet normals visible from ``wo`` (Heitz 2018).

    Parameters
    ----------
    wo : (k, 3) float
        Unit directions on either side; below the surface ``-wo`` is used.
    alpha : (k,) float
        Alpha along x (both axes unless ``alpha_y`` is given).
    u : (k, 2) float
    alpha_y : (k,) float, optional
        Alpha along y of an anisotropic GGX (:mod:`.anisotropic`).

    Returns
    -------
    (k, 3) float64
        Unit normals with ``m.z >= 0``; density :func:`ggx_visible_pdf`.
    """
    ay = alpha if alpha_y is None else alpha_y
    side = np.where(wo[:, 2] >= 0.0, 1.0, -1.0)
    w = wo * side[:, None]
    # Stretch the view direction into the configuration where GGX is the hemisphere.
    vh = np.stack([alpha * w[:, 0], ay * w[:, 1], w[:, 2]], axis=-1)
    vh /= np.linalg.norm(vh, axis=1, keepdims=True)
    lensq = vh[:, 0] ** 2 + vh[:, 1] ** 2
    has_t = lensq > 1e-14
    inv = 1.0 / np.sqrt(np.where(has_t, lensq, 1.0))
    t1 = np.where(has_t[:, None],
                  np.stack([-vh[:, 1] * inv, vh[:, 0] * inv, np.zeros_like(inv)], axis=-1),
                  np.array([1.0, 0.0, 0.0]))
    t2 = np.cross(vh, t1)
    # Uniform disk, squashed onto the part of the hemisphere's projection seen from vh.
    d = warps.sample_uniform_disk_concentric(u)
    s = 0.5 * (1.0 + vh[:, 2])
    p1 = d[:, 0]
    p2 = (1.0 - s) * np.sqrt(np.maximum(0.0, 1.0 - p1 * p1)) + s * d[:, 1]
    pz = np.sqrt(np.maximum(0.0, 1.0 - p1 * p1 - p2 * p2))
    nh = p1[:, None] * t1 + p2[:, None] * t2 + pz[:, None] * vh
    # Unstretch back to the ellipsoid configuration.
    m = np.stack([alpha * nh[:, 0], ay * nh[:, 1], np.maximum(0.0, nh[:, 2])], axis=-1)
    return m / np.maximum(np.linalg.norm(m, axis=1, keepdims=True), 1e-300)
