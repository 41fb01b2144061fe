"""Mixtures re-weighted at every hit by textures (Metallic, Alpha; :mod:`core.metallic`,
:mod:`core.alpha`).

A textured input changes a mixture's component weights from hit to hit. The exporter lays the
mixture out for one value of the input (``w_c``, summing to one); each texture source gives,
per hit, a factor per component (``f_c``), and the hit's weights are ``w_c prod f_c``,
renormalised. A component is then chosen with probability its re-weighted weight, as for every
mixture, which keeps the estimate unbiased: the expectation over the choice of the chosen BSDF
is the hit's own mixture.
"""

from __future__ import annotations

import numpy as np


def choose_weighted(weights, u_lobe):
    """Choose one component per row of ``weights (k, c)`` (>= 0, any positive sum) by
    ``u_lobe (k,)`` in [0, 1), by CDF inversion.

    Returns
    -------
    column : (k,) int64
        The chosen component (never one of weight zero).
    u_out : (k,) float64
        ``u_lobe`` remapped into the chosen component: uniform in [0, 1) again.
    """
    cdf = np.cumsum(weights, axis=1)
    total = np.maximum(cdf[:, -1], 1e-300)
    x = u_lobe * total
    j = np.minimum((cdf <= x[:, None]).sum(axis=1), weights.shape[1] - 1)
    # Never a component of weight zero (x can equal a CDF step only at its left end).
    j = np.where(weights[np.arange(j.size), j] > 0, j, np.argmax(weights > 0, axis=1))
    w = weights[np.arange(j.size), j]
    lo = np.take_along_axis(cdf, j[:, None], 1)[:, 0] - w
    u_out = np.clip((x - lo) / np.maximum(w, 1e-300), 0.0, np.nextafter(1.0, 0.0))
    return j, u_out


def combined_factors(sources, scene, rows, prim, u, v, width):
    """Product of the factors of every texture source at hits ``prim, u, v (k,)`` of triangle
    material rows ``rows (k,)``: ``hit (j,)`` (the hits some source re-weights) and their
    ``(j, width)`` factors. A source is an object with ``factors(scene, rows, prim, u, v) ->
    (hit, (j, width) factors)``."""
    factor = None
    touched = np.zeros(rows.size, bool)
    for source in sources:
        hit, f = source.factors(scene, rows, prim, u, v)
        if hit.size == 0:
            continue
        if factor is None:
            factor = np.ones((rows.size, width))
        factor[hit] *= f
        touched[hit] = True
    hit = np.nonzero(touched)[0]
    return hit, (factor[hit] if factor is not None else np.ones((0, width)))


def choose_reweighted(sources, scene, mix_rows, mix_weights, rows, prim, u, v, u_lobe,
                      material, u_out):
    """Re-choose the component of the hits that a texture source re-weights.

    Parameters
    ----------
    sources : list
        Texture sources (:class:`core.metallic.MetallicTextures`,
        :class:`core.alpha.AlphaTextures`).
    mix_rows, mix_weights : (m, c) arrays
        Component rows and weights of every material, as exported.
    rows : (k,) int
        Each hit's triangle material row; ``prim, u, v (k,)`` the hits.
    u_lobe : (k,) float
        The hits' original lobe numbers in [0, 1).
    material, u_out : (k,) arrays
        The choice made without the textures, overwritten (in place) on the re-weighted hits
        with the chosen component row and the remapped lobe number.
    """
    hit, factor = combined_factors(sources, scene, rows, prim, u, v, mix_weights.shape[1])
    if hit.size == 0:
        return
    r = rows[hit]
    j, u_new = choose_weighted(mix_weights[r] * factor, u_lobe[hit])
    material[hit] = mix_rows[r, j]
    u_out[hit] = u_new
