"""Energy compensation for multiple scattering between GGX microfacets (Blender's
*Multiscatter GGX*), the way Cycles does it.

Single-scattering GGX loses the light that bounces more than once between microfacets: a white
rough conductor reflects only ``E(mu_o) < 1`` of what arrives (0.31 at normal incidence and
roughness 1). Cycles (``microfacet_ggx_preserve_energy`` in ``kernel/closure/bsdf_microfacet.h``)
does not trace those bounces; it scales the single-scattering lobe by a factor of ``wo`` alone,
after Kulla and Conty, "Revisiting Physically Based Shading at Imageworks" (SIGGRAPH 2017
course), appendix:

``f_ms(wo, wi) = f_ss(wo, wi) (1 + F_ms (1 - E(mu_o)) / E(mu_o))``,
``F_ms = F_ss E_avg / (1 - F_ss (1 - E_avg))``

- ``E(mu, roughness)``: directional albedo of single-scattering GGX reflection with ``F = 1``
  (height-correlated Smith, reflections below the surface lost), :func:`ggx_albedo`;
- ``E_avg(roughness) = 2 int_0^1 E(mu) mu dmu``, its cosine-weighted average;
- ``F_ss``: the hemispherical average ``2 int F(mu) mu dmu`` of the lobe's Fresnel (per
  channel); for Schlick with ``F0``: ``F0 + (1 - F0) / 21`` (:func:`schlick_average`).

With ``F = 1`` the factor is ``1 / E(mu_o)``: a white rough conductor reflects everything, at
every roughness and angle (up to the table's interpolation error). A coloured ``F`` darkens and
saturates the recovered light, as repeated Fresnel reflections do. The factor depends on ``wo``
only, so sampling is unchanged (the pdf is the single-scattering one and the sample weight is
scaled); the BSDF is not reciprocal, and its adjoint (importance transport) takes the factor at
``wi`` instead.

Tables. ``E`` is stored on Cycles' grid, so that interpolation errs where Cycles' does: 32 x 32
nodes uniform in roughness and ``mu`` (``mu`` of the first node 1e-4), read bilinearly, and
``E_avg`` on the 32 roughness nodes, read linearly. Ours are computed from *our* GGX by
deterministic quadrature (:func:`ggx_albedo`, :data:`QUADRATURE` nodes per dimension; then
``E_avg`` by Gauss-Legendre in ``sqrt(mu)``) and stored in the data module
``ggx_albedo_table.py``; regenerate it with ``python -m sampling_lab.core.materials.multiscatter``.
"""

from __future__ import annotations

import sys

import numpy as np

from . import microfacet as mf
from .fresnel import fresnel_dielectric

# Cycles' grid: nodes i / (N - 1) in roughness and in mu (the first mu node is MU_MIN).
N_MU = 32
N_ROUGHNESS = 32
MU_MIN = 1e-4
# Nodes per dimension of the albedo quadrature, and Gauss-Legendre nodes of E_avg's mu integral.
QUADRATURE = 512
AVERAGE_NODES = 64


# --------------------------------------------------------------------------------------------
# Directional albedo by quadrature
# --------------------------------------------------------------------------------------------


def ggx_albedo(mu, alpha, eta=None, n=QUADRATURE):
    """Directional albedo ``E(mu) = int f_ss(wo, wi) cos_i dwi`` of GGX reflection.

    Quadrature over microfacet normals: ``E = int D(m) cos_m g(m) dm`` with
    ``g = F(wo.m) G2 (wo.m) / (cos_o cos_m)`` over the normals that reflect ``wo`` above the
    surface. ``D cos_m dm`` is uniform in ``(v, phi)`` with ``tan^2 theta_m = alpha^2 v / (1 - v)``;
    the substitution ``v = 1 - s^2`` removes the integrable ``tan theta_m`` singularity at the
    horizon, after which Gauss-Legendre in ``s`` and the midpoint rule in ``phi`` converge as
    ``n^-2`` (the integrand has kinks where ``wi`` or ``m`` meets the horizon).

    Parameters
    ----------
    mu, alpha : (k,) float
        ``cos theta_o`` in (0, 1] and GGX alpha.
    eta : (k,) float, optional
        Index of a dielectric Fresnel ``F(wo.m, eta)``; None for ``F = 1``.
    n : int
        Nodes per dimension.

    Returns
    -------
    (k,) float64
    """
    arrays = [mu, alpha] + ([] if eta is None else [eta])
    arrays = np.broadcast_arrays(*(np.asarray(v, np.float64).reshape(-1) for v in arrays))
    mu, alpha = arrays[:2]
    x, w = np.polynomial.legendre.leggauss(n)
    s = 0.5 * (x + 1.0)
    ws = w * s  # 0.5 w from [-1, 1] -> [0, 1], times dv/ds = 2 s
    phi = (np.arange(n) + 0.5) / n * np.pi  # wo lies in the xz plane: g is even in phi
    S, P = (a.reshape(-1) for a in np.meshgrid(s, phi, indexing="ij"))
    W = np.outer(ws, np.full(n, 1.0 / n)).reshape(-1)
    out = np.empty(mu.size)
    step = max(1, 2_000_000 // S.size)
    for lo in range(0, mu.size, step):
        sl = slice(lo, lo + step)
        a = alpha[sl, None]
        co = mu[sl, None]
        den = np.sqrt(S * S + a * a * (1.0 - S * S))
        cm = S / den
        sm = a * np.sqrt(1.0 - S * S) / den
        om = np.sqrt(np.maximum(0.0, 1.0 - co * co)) * sm * np.cos(P) + co * cm
        ci = 2.0 * om * cm - co
        ok = (om > 0.0) & (ci > 0.0)
        aa = np.broadcast_to(a, ci.shape)
        # G2 / cos_o, finite at grazing angles (see microfacet.ggx_visibility).
        g = 4.0 * ci * mf.ggx_visibility(co, ci, aa) * om * den / S
        if eta is not None:
            g = g * fresnel_dielectric(om.reshape(-1),
                                       np.repeat(arrays[2][sl], S.size)).reshape(om.shape)
        out[sl] = np.where(ok, g, 0.0) @ W
    return out


def ggx_average_albedo(alpha, n=QUADRATURE, n_mu=AVERAGE_NODES):
    """``E_avg = 2 int_0^1 E(mu) mu dmu`` (``F = 1``), Gauss-Legendre in ``t = sqrt(mu)``
    (``dmu = 2 t dt``, which resolves E's fast change at grazing angles). ``(k,)``."""
    alpha = np.asarray(alpha, np.float64).reshape(-1)
    x, w = np.polynomial.legendre.leggauss(n_mu)
    t = 0.5 * (x + 1.0)
    mu = t * t
    weight = 0.5 * w * 2.0 * mu * 2.0 * t  # [-1, 1] -> [0, 1], times 2 mu, times dmu/dt
    e = ggx_albedo(np.repeat(mu[None, :], alpha.size, 0).reshape(-1),
                   np.repeat(alpha, n_mu), n=n).reshape(alpha.size, n_mu)
    return e @ weight


# --------------------------------------------------------------------------------------------
# Tables
# --------------------------------------------------------------------------------------------


def table_nodes():
    """Node values ``(mu (N_MU,), roughness (N_ROUGHNESS,))`` of the tables (Cycles' grid)."""
    return (np.maximum(np.linspace(0.0, 1.0, N_MU), MU_MIN), np.linspace(0.0, 1.0, N_ROUGHNESS))


def compute_tables(n=QUADRATURE):
    """``E[mu, roughness]`` ``(N_MU, N_ROUGHNESS)`` and ``E_avg[roughness]`` ``(N_ROUGHNESS,)``.

    Roughness 0 is a perfect mirror: ``E = E_avg = 1``.
    """
    mu, roughness = table_nodes()
    alpha = mf.alpha_from_roughness(roughness)
    m, a = (v.reshape(-1) for v in np.meshgrid(mu, alpha, indexing="ij"))
    e = ggx_albedo(m, a, n=n).reshape(N_MU, N_ROUGHNESS)
    e_avg = ggx_average_albedo(alpha, n=n)
    smooth = mf.is_smooth(alpha)
    e[:, smooth] = 1.0
    e_avg[smooth] = 1.0
    return np.clip(e, 0.0, 1.0), np.clip(e_avg, 0.0, 1.0)


def _rows(values, per_line=8):
    text = [f"{v:.7f}," for v in values]
    return ["    " + " ".join(text[i:i + per_line]) for i in range(0, len(text), per_line)]


def write_tables(path):
    """Compute the tables and write the data module ``ggx_albedo_table.py`` to ``path``."""
    e, e_avg = compute_tables()
    lines = ['"""Directional albedo of single-scattering GGX reflection (F = 1), generated by',
             '``python -m sampling_lab.core.materials.multiscatter``: do not edit.', '',
             f"E[mu, roughness] on {N_MU} x {N_ROUGHNESS} nodes uniform in mu (the first at "
             f"{MU_MIN:g}) and",
             "roughness (row-major, mu slowest), and E_AVG[roughness] = 2 int E(mu) mu dmu; "
             f"quadrature of",
             f":func:`.multiscatter.ggx_albedo` with {QUADRATURE} x {QUADRATURE} nodes.",
             '"""', "", f"N_MU = {N_MU}", f"N_ROUGHNESS = {N_ROUGHNESS}", "", "E = ("]
    lines += _rows(e.reshape(-1)) + [")", "", "E_AVG = ("] + _rows(e_avg) + [")"]
    with open(path, "w", encoding="ascii") as f:
        f.write("\n".join(lines) + "\n")


_TABLES = None


def albedo_tables():
    """The stored ``(E (N_MU, N_ROUGHNESS), E_avg (N_ROUGHNESS,))`` float64."""
    global _TABLES
    if _TABLES is None:
        from . import ggx_albedo_table as t
        if (t.N_MU, t.N_ROUGHNESS) != (N_MU, N_ROUGHNESS):
            raise RuntimeError("ggx_albedo_table.py is stale: regenerate it")
        _TABLES = (np.asarray(t.E, np.float64).reshape(N_MU, N_ROUGHNESS),
                   np.asarray(t.E_AVG, np.float64))
    return _TABLES


def _linear(x, n):
    """Node index ``i (k,)`` in [0, n - 2] and fraction in [0, 1] of ``x`` in [0, 1]."""
    c = np.clip(x, 0.0, 1.0) * (n - 1)
    i = np.clip(np.floor(c).astype(np.int64), 0, n - 2)
    return i, c - i


def albedo_lookup(mu, alpha):
    """Tabulated ``(E(mu), E_avg)`` at ``|mu| (k,)`` and GGX ``alpha (k,)``, interpolated
    (bi)linearly in ``mu`` and roughness ``sqrt(alpha)``. Two ``(k,)`` arrays."""
    e, e_avg = albedo_tables()
    i, fi = _linear(np.abs(np.asarray(mu, np.float64)), N_MU)
    j, fj = _linear(np.sqrt(np.asarray(alpha, np.float64)), N_ROUGHNESS)
    top = e[i, j] * (1.0 - fj) + e[i, j + 1] * fj
    bottom = e[i + 1, j] * (1.0 - fj) + e[i + 1, j + 1] * fj
    return top * (1.0 - fi) + bottom * fi, e_avg[j] * (1.0 - fj) + e_avg[j + 1] * fj


# --------------------------------------------------------------------------------------------
# The compensation factor
# --------------------------------------------------------------------------------------------


def schlick_average(f0):
    """Hemispherical average ``2 int F mu dmu`` of Schlick's Fresnel: ``F0 + (1 - F0) / 21``."""
    f0 = np.asarray(f0, np.float64)
    return f0 + (1.0 - f0) / 21.0


def compensation(f_ss, mu, alpha):
    """Multiple-scattering factor ``1 + F_ms (1 - E(mu)) / E(mu)`` of a GGX lobe.

    Parameters
    ----------
    f_ss : (k, 3) float
        Hemispherical average of the lobe's Fresnel, in [0, 1].
    mu : (k,) float
        ``|cos theta|`` of ``wo`` (of ``wi`` for the adjoint).
    alpha : (k,) float
        GGX alpha; smooth rows (perfect mirrors, which lose nothing) get 1.

    Returns
    -------
    (k, 3) float64, >= 1 and finite.
    """
    e, e_avg = albedo_lookup(mu, alpha)
    return energy_factor(f_ss, e, e_avg, alpha)


def energy_factor(f_ss, e, e_avg, alpha):
    """``1 + F_ms (1 - E) / E`` with ``F_ms = F_ss E_avg / (1 - F_ss (1 - E_avg))`` from a
    lobe's albedo ``e (k,)`` at the view angle and its average ``e_avg (k,)`` (conductors here,
    glass in :mod:`core.materials.glass_albedo`); ``f_ss (k, 3)`` is clipped to [0, 1].
    Returns ``(k, 3)``; 1 on smooth rows."""
    f_ss = np.clip(np.asarray(f_ss, np.float64), 0.0, 1.0)
    e_avg = np.asarray(e_avg, np.float64)[:, None]
    f_ms = f_ss * e_avg / np.maximum(1.0 - f_ss * (1.0 - e_avg), 1e-12)
    missing = (1.0 - e) / np.maximum(e, 1e-6)
    factor = 1.0 + f_ms * missing[:, None]
    return np.where(mf.is_smooth(alpha)[:, None], 1.0, factor)


if __name__ == "__main__":
    import os
    import time

    t0 = time.perf_counter()
    target = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__),
                                                               "ggx_albedo_table.py")
    write_tables(target)
    print(f"wrote {target} in {time.perf_counter() - t0:.1f} s")
