"""A connection end's BSDF values in one call: ``f |cos|`` toward a direction and the densities
of sampling either direction from the other, from one dispatch and one gather of each family's
rows.

A bidirectional connection reads three numbers of each end's BSDF: ``f(wo, wi) |cos_i|`` for
its value, and for its MIS weight the solid-angle densities ``p(wo -> wi)`` and
``p(wi -> wo)``. :func:`core.materials.bsdf.eval_bsdf` and two calls of
:func:`~core.materials.bsdf.pdf_bsdf` would each group the rows by kind, gather every family's
parameters and the coat's and sheen's rows again; :func:`eval_with_pdfs` does that once and
calls the same family functions on the same arrays, so its values equal the three calls' to
the last bit (``tests/core/test_bsdf_values.py``). Rows with a bump normal (whose correction
re-evaluates the kinds through their own dispatch) take the three calls.
"""

from __future__ import annotations

import numpy as np

from . import coat, sheen
from .bsdf import check_rows, eval_bsdf, kind_groups, kind_rows, pdf_bsdf
from .coat import coat_rows
from .dielectric import RADIANCE
from .families import FAMILIES


def eval_with_pdfs(params, wo, wi, mode=RADIANCE):
    """``f |cos theta_i|`` and both directions' densities of the non-delta lobes.

    Parameters
    ----------
    params : BSDFParams
        ``k`` rows.
    wo, wi : (k, 3) float
        Unit local directions.
    mode : {'radiance', 'importance'}

    Returns
    -------
    f : (k, 3) float64
        ``eval_bsdf(params, wo, wi, mode)``.
    pdf_wi : (k,) float64
        ``pdf_bsdf(params, wo, wi)``: sampling ``wi`` given ``wo``.
    pdf_wo : (k,) float64
        ``pdf_bsdf(params, wi, wo)``: sampling ``wo`` given ``wi``.
    """
    wo, wi = np.asarray(wo, np.float64), np.asarray(wi, np.float64)
    if params.bump_normal is not None:
        return eval_bsdf(params, wo, wi, mode), pdf_bsdf(params, wo, wi), pdf_bsdf(params, wi, wo)
    check_rows(params, wo, mode)
    f, pdf_wi, pdf_wo = _kinds(params, wo, wi, mode)
    for rows, layer in ((coat_rows(params), _coated), (sheen.sheen_rows(params), _sheened)):
        if rows.size:
            f[rows], pdf_wi[rows], pdf_wo[rows] = layer(
                params.take(rows), wo[rows], wi[rows], mode, f[rows], pdf_wi[rows], pdf_wo[rows])
    return f, pdf_wi, pdf_wo


def _kinds(params, wo, wi, mode):
    """The three values of the rows' own kinds (no coat or sheen), each family's rows gathered
    once."""
    k = len(params)
    f, pdf_wi, pdf_wo = np.zeros((k, 3)), np.zeros(k), np.zeros(k)
    for kind, rows in kind_groups(params):
        ev, pdf = FAMILIES[kind][:2]
        if rows is None:
            return ev(params, wo, wi, mode), pdf(params, wo, wi), pdf(params, wi, wo)
        p, wo_r, wi_r = kind_rows(params, kind, rows), wo[rows], wi[rows]
        f[rows], pdf_wi[rows], pdf_wo[rows] = ev(p, wo_r, wi_r, mode), pdf(p, wo_r, wi_r), pdf(
            p, wi_r, wo_r)
    return f, pdf_wi, pdf_wo


def _coated(p, wo, wi, mode, f, pdf_wi, pdf_wo):
    """The coat over the rows' values (:mod:`.coat`)."""
    return (coat.eval_coated(p, wo, wi, f, mode), coat.pdf_coated(p, wo, wi, pdf_wi),
            coat.pdf_coated(p, wi, wo, pdf_wo))


def _sheened(p, wo, wi, mode, f, pdf_wi, pdf_wo):
    """The sheen over the rows' values (:mod:`.sheen`)."""
    return (sheen.eval_sheened(p, wo, wi, f, mode), sheen.pdf_sheened(p, wo, wi, pdf_wi),
            sheen.pdf_sheened(p, wi, wo, pdf_wo))
