"""BSDF cost: rows per second of sample + eval + pdf for every material model, in one run.

``python -m sampling_lab bench-materials`` calls :func:`run`: for each model (diffuse, the
Principled specular layer single- and multiple-scattering, with a coat, with Specular Tint,
with a sheen, rough metal, anisotropic metal, rough glass single- and multiple-scattering, ...) it times ``repeats`` rounds of
:func:`core.materials.bsdf.sample_bsdf`, ``eval_bsdf`` and ``pdf_bsdf`` on ``rows`` random
directions and prints the best rate and its ratio to plain diffuse, measured side by side so
that the ratios hold on a loaded machine. Batches where only some rows are coated, have a
sheen or are anisotropic show that the other rows do not pay for the layer. Figures only, never asserted.
"""

from __future__ import annotations

import time

import numpy as np

from .common import loadavg, machine_summary


def models(k):
    """``{name: BSDFParams}`` of ``k`` rows each."""
    from ..core.materials import bsdf as B

    coat = dict(coat_weight=1.0, coat_roughness=0.1, coat_ior=1.5, coat_tint=(0.9, 0.8, 0.7))
    tenth = np.where(np.arange(k) % 10 == 0, 1.0, 0.0)
    return {
        "diffuse": B.make_params(B.KIND_DIFFUSE, 0.5, k=k),
        "specular layer (GGX)": B.make_params(B.KIND_LAYERED, 0.5, 0.4, 1.5, k=k),
        "specular layer, Specular Tint": B.make_params(B.KIND_LAYERED, 0.5, 0.4, 1.5,
                                                       tint=(1.0, 0.5, 0.2), k=k),
        "specular layer (Multiscatter)": B.make_params(B.KIND_LAYERED_MS, 0.5, 0.4, 1.5, k=k),
        "specular layer + coat": B.make_params(B.KIND_LAYERED, 0.5, 0.4, 1.5, k=k, **coat),
        "specular layer, coat on 10 % of rows": B.make_params(
            B.KIND_LAYERED, 0.5, 0.4, 1.5, k=k, **{**coat, "coat_weight": tenth}),
        "specular layer + sheen": B.make_params(B.KIND_LAYERED, 0.5, 0.4, 1.5, k=k,
                                                sheen_weight=1.0, sheen_roughness=0.3),
        "specular layer, sheen on 10 % of rows": B.make_params(
            B.KIND_LAYERED, 0.5, 0.4, 1.5, k=k, sheen_weight=tenth, sheen_roughness=0.3),
        "metal (Multiscatter)": B.make_params(B.KIND_CONDUCTOR_MS, 0.9, 0.4, k=k),
        "metal (Multiscatter), anisotropic": B.make_params(
            B.KIND_CONDUCTOR_MS, 0.9, 0.4, k=k, aniso_scale=2.0, aniso_rotation=0.3),
        "metal, anisotropic on 10 % of rows": B.make_params(
            B.KIND_CONDUCTOR_MS, 0.9, 0.4, k=k, aniso_scale=np.where(tenth > 0, 2.0, 1.0)),
        "metal + coat": B.make_params(B.KIND_CONDUCTOR_MS, 0.9, 0.4, k=k, **coat),
        "glass (GGX)": B.make_params(B.KIND_DIELECTRIC, 1.0, 0.4, 1.5, k=k),
        "glass (Multiscatter)": B.make_params(B.KIND_DIELECTRIC_MS, 1.0, 0.4, 1.5, k=k),
    }


def _round(params, wo, wi, u_lobe, u):
    from ..core.materials import bsdf as B

    B.sample_bsdf(params, wo, u_lobe, u)
    B.eval_bsdf(params, wo, wi)
    B.pdf_bsdf(params, wo, wi)


def run(rows=100_000, repeats=5, progress=print):
    """Time every model and print its rate: ``{name: rows per second}``."""
    rng = np.random.default_rng(1)
    wo, wi = rng.normal(size=(rows, 3)), rng.normal(size=(rows, 3))
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    u_lobe, u = rng.random(rows), rng.random((rows, 2))
    progress(machine_summary())
    progress(f"load average before: {loadavg()}")
    rates = {}
    table = models(rows)
    first = np.arange(64)
    for name, params in table.items():  # tables decoded, imports done
        _round(params.take(first), wo[first], wi[first], u_lobe[first], u[first])
    for _ in range(repeats):  # interleaved, so that load changes hit every model alike
        for name, params in table.items():
            t0 = time.perf_counter()
            _round(params, wo, wi, u_lobe, u)
            rate = rows / (time.perf_counter() - t0)
            rates[name] = max(rates.get(name, 0.0), rate)
    base = rates["diffuse"]
    for name, rate in rates.items():
        progress(f"{name:40s} {rate / 1e6:7.3f} M rows/s (sample + eval + pdf)  "
                 f"x{base / rate:5.2f} the time of diffuse")
    progress(f"load average after: {loadavg()}")
    return rates
