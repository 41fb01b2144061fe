"""Multiscatter GGX for rough dielectrics (Blender's Glass BSDF and Principled transmission left
at *Multiscatter GGX*), the way Cycles compensates them.

A single-scattering rough dielectric loses the light that bounces more than once between its
microfacets: its albedo ``E(mu_o) = int (f_r + f_t) |cos_i| dwi`` (reflection plus
transmission, flux terms: without the ``1 / eta^2`` of radiance) is below one, although a
lossless interface should keep everything. Cycles (``microfacet_ggx_preserve_energy`` in
``kernel/closure/bsdf_microfacet.h``, with Fresnel term ``F_ss = 1`` for glass) divides the
whole lobe by ``E(mu_o)``, looked up in tables of its own single-scattering glass for the
index seen from ``wo``'s side (one table for ``eta > 1``, one for ``eta < 1``, light leaving
the interior). Kulla and Conty, "Revisiting Physically Based Shading at Imageworks" (SIGGRAPH
2017 course), is the reference for the method.

``f_ms(wo, wi) = f_ss(wo, wi) / E(mu_o, eta_o)`` for white glass; a coloured Glass BSDF gets
Cycles' darkening with ``F_ss`` = its colour (``1 + F_ms (1 - E) / E``, as
:mod:`.multiscatter`, with ``E_avg`` the table's cosine-weighted average). Sampling is
unchanged (the pdf is the single-scattering one; the sample weight is scaled); the BSDF is not
reciprocal, and its adjoint (importance mode) takes the factor at ``wi`` with the index seen
from ``wi``.

Tables. ``E`` on :data:`N_MU` x :data:`N_ROUGHNESS` x :data:`N_Z` nodes uniform in
``sqrt(mu)``, roughness and ``z = sqrt((n - 1) / (n + 1))`` (``n`` = the index or its
reciprocal, >= 1), for both sides, read trilinearly. They are computed from *our*
single-scattering dielectric (:mod:`.dielectric`) by deterministic quadrature over its
visible-normal sample space, where both lobes are weighted by their Fresnel probability
(``F w_r + (1 - F) w_t``: a smooth integrand, :data:`QUADRATURE` nodes per dimension), and
stored in the data module ``glass_albedo_table.py``; regenerate it with
``python -m sampling_lab.core.materials.glass_albedo``.
"""

from __future__ import annotations

import base64
import sys

import numpy as np

from . import microfacet as mf
from .frame import dot
from .fresnel import fresnel_dielectric
from .multiscatter import energy_factor

N_MU = 16
N_ROUGHNESS = 16
N_Z = 16
QUADRATURE = 64
# Smallest node of mu (grazing directions are interpolated toward it).
MU_MIN = 1e-3


def glass_albedo(mu, alpha, eta, n=QUADRATURE):
    """Albedo ``E (k,)`` of the single-scattering rough dielectric seen at ``cos = mu (k,)``
    from outside an interface of index ratio ``eta (k,)`` (``< 1``: from the denser side),
    by the midpoint rule on ``n x n`` visible-normal samples."""
    from .dielectric import IMPORTANCE, sample_dielectric
    mu = np.asarray(mu, np.float64)
    k = mu.size
    t = (np.arange(n) + 0.5) / n
    u = np.stack(np.meshgrid(t, t, indexing="ij"), axis=-1).reshape(-1, 2)
    rows = np.repeat(np.arange(k), u.shape[0])
    uu = np.tile(u, (k, 1))
    wo = np.stack([np.sqrt(np.maximum(1.0 - mu * mu, 0.0)), np.zeros(k), mu], axis=1)[rows]
    a, e = np.asarray(alpha, np.float64)[rows], np.asarray(eta, np.float64)[rows]
    white = np.ones((rows.size, 3))
    f = fresnel_dielectric(dot(wo, mf.sample_ggx_visible(wo, a, uu)), e)
    w_r = sample_dielectric(e, a, white, white, wo, np.zeros(rows.size), uu, IMPORTANCE)[1]
    w_t = sample_dielectric(e, a, white, white, wo, np.full(rows.size, 1.0 - 1e-12), uu,
                            IMPORTANCE)[1]
    per = f * w_r[:, 0] + (1.0 - f) * w_t[:, 0]
    return per.reshape(k, -1).mean(axis=1)


def table_nodes():
    """Node values ``(mu, alpha, n)`` of the axes (``n >= 1``, the index or its reciprocal)."""
    mu = np.maximum(np.linspace(0.0, 1.0, N_MU) ** 2, MU_MIN)
    alpha = np.maximum(np.linspace(0.0, 1.0, N_ROUGHNESS) ** 2, mf.ALPHA_MIN)
    z2 = np.minimum(np.linspace(0.0, 1.0, N_Z) ** 2, 1.0 - 1e-6)
    return mu, alpha, (1.0 + z2) / (1.0 - z2)


def compute_tables(n=QUADRATURE):
    """``(E_enter, E_leave)``, each ``(N_MU, N_ROUGHNESS, N_Z)``: for ``eta = n`` and ``1 / n``.
    Smooth nodes (roughness 0) and index-matched ones (``n = 1``) are exactly one."""
    mu, alpha, ior = table_nodes()
    m, a, x = (v.reshape(-1) for v in np.meshgrid(mu, alpha, ior, indexing="ij"))
    tables = []
    for eta in (x, 1.0 / x):
        e = np.ones(m.size)
        rough = ~mf.is_smooth(a) & (np.abs(eta - 1.0) > 1e-4)
        for chunk in np.array_split(np.nonzero(rough)[0], max(1, rough.sum() // 512)):
            e[chunk] = glass_albedo(m[chunk], a[chunk], eta[chunk], n)
        tables.append(np.clip(e, 0.0, 1.0).reshape(N_MU, N_ROUGHNESS, N_Z))
    return tables


def write_tables(path):
    """Compute the tables and write the data module ``glass_albedo_table.py`` to ``path``."""
    lines = []
    for table in compute_tables():
        q = np.round(np.clip(table, 0.0, 1.0) * 65535.0).astype("<u2")
        raw = base64.b64encode(np.ascontiguousarray(q).tobytes()).decode("ascii")
        lines.append([raw[i:i + 92] for i in range(0, len(raw), 92)])
    with open(path, "w", encoding="ascii") as f:
        f.write('"""Albedo of the single-scattering GGX dielectric, generated by\n'
                '``python -m sampling_lab.core.materials.glass_albedo``: do not edit.\n\n'
                f"E[mu, roughness, z] on {N_MU} x {N_ROUGHNESS} x {N_Z} nodes (see "
                ":mod:`.glass_albedo`), entering\n(``eta = n``) and leaving (``eta = 1 / n``), "
                "as little-endian uint16 E * 65535, base64.\n"
                '"""\n\n')
        f.write(f"N_MU = {N_MU}\nN_ROUGHNESS = {N_ROUGHNESS}\nN_Z = {N_Z}\n\n")
        for name, text in zip(("ENTER", "LEAVE"), lines):
            f.write(f"{name} = (\n")
            for line in text:
                f.write(f'    "{line}"\n')
            f.write(")\n")


_TABLES = None


def albedo_tables():
    """The stored ``(E_enter, E_leave)`` tables, float64 (decoded on first use)."""
    global _TABLES
    if _TABLES is None:
        from . import glass_albedo_table as t
        if (t.N_MU, t.N_ROUGHNESS, t.N_Z) != (N_MU, N_ROUGHNESS, N_Z):
            raise RuntimeError("glass_albedo_table.py is stale: regenerate it")
        _TABLES = tuple(np.frombuffer(base64.b64decode("".join(text)), "<u2")
                        .astype(np.float64).reshape(N_MU, N_ROUGHNESS, N_Z) / 65535.0
                        for text in (t.ENTER, t.LEAVE))
    return _TABLES


def _trilinear(table, coords):
    idx, frac = [], []
    for c, n in zip(coords, table.shape):
        c = np.clip(c, 0.0, 1.0) * (n - 1)
        i = np.clip(np.floor(c).astype(np.int64), 0, n - 2)
        idx.append(i)
        frac.append(c - i)
    out = np.zeros(coords[0].shape)
    for corner in range(8):
        d = [(corner >> b) & 1 for b in range(3)]
        w = np.ones(out.shape)
        for b in range(3):
            w = w * (frac[b] if d[b] else 1.0 - frac[b])
        out += w * table[idx[0] + d[0], idx[1] + d[1], idx[2] + d[2]]
    return out


def albedo_lookup(mu, alpha, eta):
    """Tabulated ``E (k,)`` at ``|cos| = mu``, GGX ``alpha`` and the index ratio ``eta`` seen
    from that direction's side (``< 1``: from the denser side); 1 for smooth rows."""
    enter, leave = albedo_tables()
    mu = np.clip(np.abs(np.asarray(mu, np.float64)), MU_MIN, 1.0)
    eta = np.asarray(eta, np.float64)
    n = np.where(eta < 1.0, 1.0 / np.maximum(eta, 1e-12), eta)
    z = np.sqrt(np.clip((n - 1.0) / (n + 1.0), 0.0, 1.0))
    coords = (np.sqrt((mu - MU_MIN) / (1.0 - MU_MIN)), np.sqrt(np.clip(alpha, 0.0, 1.0)), z)
    e = np.where(eta < 1.0, _trilinear(leave, coords), _trilinear(enter, coords))
    return np.where(mf.is_smooth(alpha), 1.0, e)


_AVERAGES = None


def average_tables():
    """``E_avg = 2 int_0^1 E(mu) mu dmu`` per (roughness, z) node of both tables,
    ``(N_ROUGHNESS, N_Z)`` each (Gauss-Legendre over the interpolated table, on first use)."""
    global _AVERAGES
    if _AVERAGES is None:
        x, w = np.polynomial.legendre.leggauss(32)
        t = 0.5 * (x + 1.0)                      # sqrt(mu)
        r, z = np.meshgrid(np.linspace(0, 1, N_ROUGHNESS), np.linspace(0, 1, N_Z),
                           indexing="ij")
        out = []
        for table in albedo_tables():
            mu = t * t
            coords = (np.sqrt((np.maximum(mu, MU_MIN) - MU_MIN) / (1.0 - MU_MIN))[None, None, :]
                      * np.ones(r.shape + (1,)), r[..., None] * np.ones(t.shape),
                      z[..., None] * np.ones(t.shape))
            e = _trilinear(table, coords)
            out.append(np.sum(e * 2.0 * mu * 2.0 * t * 0.5 * w, axis=-1))
        _AVERAGES = tuple(out)
    return _AVERAGES


def _bilinear(table, a, b):
    out = np.zeros(np.shape(a))
    idx, frac = [], []
    for c, n in zip((a, b), table.shape):
        c = np.clip(c, 0.0, 1.0) * (n - 1)
        i = np.clip(np.floor(c).astype(np.int64), 0, n - 2)
        idx.append(i)
        frac.append(c - i)
    for da in (0, 1):
        for db in (0, 1):
            w = (frac[0] if da else 1 - frac[0]) * (frac[1] if db else 1 - frac[1])
            out += w * table[idx[0] + da, idx[1] + db]
    return out


def compensation(mu, alpha, eta, f_ss):
    """Cycles' Multiscatter GGX factor ``(k, 3)`` of a rough dielectric at ``|cos| = mu`` with
    index ratio ``eta`` seen from that side: ``1 + F_ms (1 - E) / E``,
    ``F_ms = F_ss E_avg / (1 - F_ss (1 - E_avg))`` with ``F_ss (k, 3)`` the Glass BSDF's
    transmission tint (white glass: ``1 / E``); 1 for smooth rows."""
    e = np.maximum(albedo_lookup(mu, alpha, eta), 1e-3)
    eta = np.asarray(eta, np.float64)
    n = np.where(eta < 1.0, 1.0 / np.maximum(eta, 1e-12), eta)
    z = np.sqrt(np.clip((n - 1.0) / (n + 1.0), 0.0, 1.0))
    enter, leave = average_tables()
    r = np.sqrt(np.clip(alpha, 0.0, 1.0))
    e_avg = np.where(eta < 1.0, _bilinear(leave, r, z), _bilinear(enter, r, z))
    return energy_factor(f_ss, e, e_avg, alpha)


if __name__ == "__main__":
    import os
    import time

    t0 = time.perf_counter()
    target = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__),
                                                               "glass_albedo_table.py")
    write_tables(target)
    print(f"wrote {target} in {time.perf_counter() - t0:.1f} s")
