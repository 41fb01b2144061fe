"""The BSDF kinds: their codes, the lobe labels of sampled directions, and the adapters that put
each family (:mod:`.lambert`, :mod:`.conductor`, :mod:`.dielectric`, :mod:`.layered`) in the
common protocol :mod:`.bsdf` dispatches on: ``f(p, wo, wi, mode)``, ``pdf(p, wo, wi)``,
``sample(p, wo, u_lobe, u, mode) -> (wi, weight, pdf, delta)`` and ``label(p, wo, u_lobe,
delta)``, on the rows of one kind (see :mod:`.bsdf` for the contract)."""

from __future__ import annotations

import numpy as np

from ..sampling.warps import INV_PI, cosine_hemisphere_pdf, sample_cosine_hemisphere
from . import anisotropic, conductor, dielectric, layered
from .anisotropic import anisotropic_part, rotate

# Kind codes of the material table (scene.MAT_DIFFUSE == KIND_DIFFUSE == 0).
KIND_DIFFUSE = 0
KIND_CONDUCTOR = 1
KIND_DIELECTRIC = 2
KIND_LAYERED = 3
# A BSDF kind only: material tables say "multiscatter" with a column (see the module docstring).
KIND_CONDUCTOR_MS = 4
KIND_LAYERED_MS = 5
KIND_DIELECTRIC_MS = 6
KINDS = (KIND_DIFFUSE, KIND_CONDUCTOR, KIND_DIELECTRIC, KIND_LAYERED, KIND_CONDUCTOR_MS,
         KIND_LAYERED_MS, KIND_DIELECTRIC_MS)
KIND_NAMES = {KIND_DIFFUSE: "diffuse", KIND_CONDUCTOR: "conductor",
              KIND_DIELECTRIC: "dielectric", KIND_LAYERED: "layered",
              KIND_CONDUCTOR_MS: "conductor_ms", KIND_LAYERED_MS: "layered_ms",
              KIND_DIELECTRIC_MS: "dielectric_ms"}

# Labels of sampled lobes (bits, as Cycles' LABEL_*).
LOBE_REFLECT = 1
LOBE_TRANSMIT = 2
LOBE_DIFFUSE = 4
LOBE_GLOSSY = 8
LOBE_SINGULAR = 16


# --------------------------------------------------------------------------------------------
# Families in the common protocol: f(p, wo, wi, mode), pdf(p, wo, wi), sample(p, wo, u_lobe, u,
# mode) -> (wi, weight, pdf, delta), on the rows of one kind.
# --------------------------------------------------------------------------------------------


def _diffuse_side(wo):
    """Two-sided Lambert: ``+1`` where ``wo`` is above the local surface, else ``-1`` ``(k,)``.
    The normal on ``wo``'s side is ``(0, 0, side)``, so a cosine with it is ``side * w_z``:
    exactly what :mod:`.lambert`'s dot products with that normal give, without them."""
    return np.where(wo[:, 2] >= 0.0, 1.0, -1.0)


def _diffuse_eval(p, wo, wi, mode):
    cos = _diffuse_side(wo) * wi[:, 2]
    return p.color * (np.maximum(cos, 0.0) * INV_PI)[:, None]


def _diffuse_pdf(p, wo, wi):
    return cosine_hemisphere_pdf(_diffuse_side(wo) * wi[:, 2])


def _diffuse_sample(p, wo, u_lobe, u, mode):
    # Cosine-weighted directions around (0, 0, side): the hemisphere sample with its y and z
    # mirrored below the surface, as :func:`.lambert.sample_lambert`'s frame around -Z maps it.
    # (Column by column and without np.where when every pdf is positive: NumPy's broadcasts
    # of (k, 1) against (k, 3) cost several times the plain operations.)
    wi = sample_cosine_hemisphere(u)
    pdf = cosine_hemisphere_pdf(wi[:, 2])
    side = _diffuse_side(wo)
    wi[:, 1] *= side
    wi[:, 2] *= side
    weight = p.color.copy()
    bad = ~(pdf > 0.0)
    if bad.any():
        wi[bad] = 0.0
        weight[bad] = 0.0
    return wi, weight, pdf, np.zeros(wo.shape[0], bool)


def _diffuse_kind(p, wo, u_lobe, delta):
    return np.full(wo.shape[0], LOBE_DIFFUSE, np.uint8)


def _glossy_kind(p, wo, u_lobe, delta):
    return np.where(delta, LOBE_SINGULAR, LOBE_GLOSSY).astype(np.uint8)


def _layered_kind(p, wo, u_lobe, delta):
    coat = u_lobe < layered.coat_probability(p.color, anisotropic.mean_alpha(p), p.eta, p.tint,
                                             wo,
                                             multiscatter=bool(np.any(p.kind == KIND_LAYERED_MS)))
    return np.where(delta, LOBE_SINGULAR,
                    np.where(coat, LOBE_GLOSSY, LOBE_DIFFUSE)).astype(np.uint8)


# Anisotropic rows (:mod:`.anisotropic`) of conductors and specular layers: evaluated by
# ``aniso(q, ax, ay, wo, wi)`` in the tangent frame turned by their rotation, the other rows by
# ``iso(p, wo, wi)``; batches without anisotropic rows go straight to ``iso``. When most rows
# are isotropic, ``iso`` runs on all of them (cheaper than gathering the rest).
def _rest(k, rows):
    """Rows of ``range(k)`` not in ``rows``, or None when ``iso`` should run on all rows."""
    return np.setdiff1d(np.arange(k), rows) if 2 * rows.size >= k else None


def _split_eval(p, wo, wi, iso, aniso):
    rows, q, ax, ay, angle = anisotropic_part(p)
    if q is None:
        return iso(p, wo, wi)
    part = aniso(q, ax, ay, rotate(wo[rows], angle), rotate(wi[rows], angle))
    rest = _rest(len(p), rows)
    if rest is None:
        out = iso(p, wo, wi)
    else:
        out = np.zeros((len(p),) + part.shape[1:])
        if rest.size:
            out[rest] = iso(p.take(rest), wo[rest], wi[rest])
    out[rows] = part
    return out


def _split_sample(p, wo, u_lobe, u, iso, aniso):
    """As :func:`_split_eval` for samplers ``(p, wo, u_lobe, u) -> (wi, weight, pdf, delta)``."""
    rows, q, ax, ay, angle = anisotropic_part(p)
    if q is None:
        return iso(p, wo, u_lobe, u)
    k = len(p)
    rest = _rest(k, rows)
    if rest is None:
        out = iso(p, wo, u_lobe, u)
    else:
        out = (np.zeros((k, 3)), np.zeros((k, 3)), np.zeros(k), np.zeros(k, bool))
        if rest.size:
            parts = iso(p.take(rest), wo[rest], u_lobe[rest], u[rest])
            for column, value in zip(out, parts):
                column[rest] = value
    wi, weight, pdf, delta = out
    wi_r, weight[rows], pdf[rows], delta[rows] = aniso(q, ax, ay, rotate(wo[rows], angle),
                                                       u_lobe[rows], u[rows])
    wi[rows] = rotate(wi_r, -angle)
    return out


def _conductor_eval(p, wo, wi, mode, ms=False):
    return _split_eval(
        p, wo, wi,
        lambda q, a, b: conductor.eval_conductor(q.color, q.alpha, a, b, multiscatter=ms,
                                                 mode=mode),
        lambda q, ax, ay, a, b: anisotropic.eval_conductor_aniso(q.color, ax, ay, a, b, ms,
                                                                 mode))


def _conductor_pdf(p, wo, wi):
    return _split_eval(p, wo, wi, lambda q, a, b: conductor.pdf_conductor(q.alpha, a, b),
                       lambda q, ax, ay, a, b: anisotropic.pdf_conductor_aniso(ax, ay, a, b))


def _conductor_sample(p, wo, u_lobe, u, mode, ms=False):
    return _split_sample(
        p, wo, u_lobe, u,
        lambda q, a, ul, uu: conductor.sample_conductor(q.color, q.alpha, a, uu,
                                                        multiscatter=ms, mode=mode),
        lambda q, ax, ay, a, ul, uu: anisotropic.sample_conductor_aniso(q.color, ax, ay, a,
                                                                        uu, ms, mode))


def _conductor_ms_eval(p, wo, wi, mode):
    return _conductor_eval(p, wo, wi, mode, ms=True)


def _conductor_ms_sample(p, wo, u_lobe, u, mode):
    return _conductor_sample(p, wo, u_lobe, u, mode, ms=True)


def _dielectric_eval(p, wo, wi, mode):
    return dielectric.eval_dielectric(p.eta, p.alpha, p.tint, p.color, wo, wi, mode)


def _dielectric_pdf(p, wo, wi):
    return dielectric.pdf_dielectric(p.eta, p.alpha, wo, wi)


def _dielectric_sample(p, wo, u_lobe, u, mode):
    return dielectric.sample_dielectric(p.eta, p.alpha, p.tint, p.color, wo, u_lobe, u, mode)


def _layered_eval(p, wo, wi, mode, ms=False):
    out = _split_eval(
        p, wo, wi,
        lambda q, a, b: layered.eval_layered(q.color, q.alpha, q.eta, q.tint, a, b, mode,
                                             multiscatter=ms),
        lambda q, ax, ay, a, b: layered.eval_layered(q.color, ax, q.eta, q.tint, a, b, mode,
                                                     multiscatter=ms, alpha_y=ay))
    rows = _base_rows(p)
    if rows.size:
        q = p.take(rows)
        out[rows] = layered.base_normal_eval(out[rows], q.color, q.alpha, q.eta, q.tint,
                                             wo[rows], wi[rows], q.base_normal, mode, ms)
    return out


def _layered_pdf(p, wo, wi, ms=False):
    out = _split_eval(
        p, wo, wi,
        lambda q, a, b: layered.pdf_layered(q.color, q.alpha, q.eta, q.tint, a, b,
                                            multiscatter=ms),
        lambda q, ax, ay, a, b: layered.pdf_layered(q.color, ax, q.eta, q.tint, a, b,
                                                    multiscatter=ms, alpha_y=ay))
    rows = _base_rows(p)
    if rows.size:
        q = p.take(rows)
        out[rows] = layered.base_normal_pdf(out[rows], q.color, q.alpha, q.eta, q.tint,
                                            wo[rows], wi[rows], q.base_normal, ms)
    return out


def _layered_sample(p, wo, u_lobe, u, mode, ms=False):
    wi, weight, pdf, delta = _split_sample(
        p, wo, u_lobe, u,
        lambda q, a, ul, uu: layered.sample_layered(q.color, q.alpha, q.eta, q.tint, a, ul, uu,
                                                    mode, multiscatter=ms),
        lambda q, ax, ay, a, ul, uu: layered.sample_layered(
            q.color, ax, q.eta, q.tint, a, ul, uu, mode, multiscatter=ms, alpha_y=ay))
    rows = _base_rows(p)
    rows = rows[~delta[rows]]
    if rows.size:
        # Base-normal rows: the base's directions around its own normal, and every non-delta
        # weight from the changed mixture (eval / pdf at the sampled direction).
        q, w = p.take(rows), wo[rows]
        d = layered.base_normal_sample(wi[rows], q.color, q.alpha, q.eta, q.tint, w,
                                       u_lobe[rows], u[rows], q.base_normal, ms)
        f = _layered_eval(q, w, d, mode, ms)
        density = _layered_pdf(q, w, d, ms)
        good = density > 0.0
        wi[rows] = np.where(good[:, None], d, 0.0)
        weight[rows] = np.where(good[:, None], f / np.where(good, density, 1.0)[:, None], 0.0)
        pdf[rows] = np.where(good, density, 0.0)
    return wi, weight, pdf, delta


def _base_rows(p):
    """Rows ``(j,)`` of layered kinds with a base normal (:mod:`.layered`)."""
    if getattr(p, "base_normal", None) is None:
        return np.zeros(0, np.int64)
    return np.nonzero(np.any(p.base_normal != 0.0, axis=1))[0]


def _dielectric_ms_eval(p, wo, wi, mode):
    return dielectric.eval_dielectric(p.eta, p.alpha, p.tint, p.color, wo, wi, mode,
                                      multiscatter=True)


def _dielectric_ms_sample(p, wo, u_lobe, u, mode):
    return dielectric.sample_dielectric(p.eta, p.alpha, p.tint, p.color, wo, u_lobe, u, mode,
                                        multiscatter=True)


def _layered_ms_eval(p, wo, wi, mode):
    return _layered_eval(p, wo, wi, mode, ms=True)


def _layered_ms_pdf(p, wo, wi):
    return _layered_pdf(p, wo, wi, ms=True)


def _layered_ms_sample(p, wo, u_lobe, u, mode):
    return _layered_sample(p, wo, u_lobe, u, mode, ms=True)


FAMILIES = {
    KIND_DIFFUSE: (_diffuse_eval, _diffuse_pdf, _diffuse_sample, _diffuse_kind),
    KIND_CONDUCTOR: (_conductor_eval, _conductor_pdf, _conductor_sample, _glossy_kind),
    KIND_DIELECTRIC: (_dielectric_eval, _dielectric_pdf, _dielectric_sample, _glossy_kind),
    KIND_LAYERED: (_layered_eval, _layered_pdf, _layered_sample, _layered_kind),
    KIND_CONDUCTOR_MS: (_conductor_ms_eval, _conductor_pdf, _conductor_ms_sample, _glossy_kind),
    KIND_LAYERED_MS: (_layered_ms_eval, _layered_ms_pdf, _layered_ms_sample, _layered_kind),
    KIND_DIELECTRIC_MS: (_dielectric_ms_eval, _dielectric_pdf, _dielectric_ms_sample,
                         _glossy_kind),
}

