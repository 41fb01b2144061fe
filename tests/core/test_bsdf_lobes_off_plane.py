"""Every lobe's samples follow its pdf when the lobe lies off the plane of incidence: views at
azimuths other than 0 and pi, sharp and rough, anisotropic highlights, a tilted coat normal,
sheen, and Multiscatter GGX layers (the checker, :mod:`tests.sphere_chi2`, places its dense
cells at the pdf's largest value wherever it is; chi-square at its Bonferroni ``ALPHA``)."""

from __future__ import annotations

import dataclasses
import math
import zlib

import numpy as np
import pytest

from sampling_lab.core.materials import bsdf as B
from tests.sphere_chi2 import chi_square_bsdf_rows

TILTED = np.array([0.35, -0.2, 0.915]) / np.linalg.norm([0.35, -0.2, 0.915])


def _wo(z, phi):
    s = math.sqrt(1.0 - z * z)
    return np.array([s * math.cos(phi), s * math.sin(phi), z])


def _check(params, z, phi, eta, what):
    chi_square_bsdf_rows(params, _wo(z, phi), eta, seed=zlib.crc32(what.encode()), what=what)


# (kind, roughness, anisotropy scale, rotation, cos theta_o, view azimuth)
ANISOTROPIC = [(B.KIND_CONDUCTOR, 0.05, 3.0, 0.7, 0.6, 1.3),
               (B.KIND_CONDUCTOR, 0.15, 0.3, -0.4, 0.2, 2.2),
               (B.KIND_CONDUCTOR_MS, 0.1, 2.5, 1.1, 0.8, 4.0),
               (B.KIND_LAYERED, 0.08, 3.0, 0.3, 0.5, 5.5)]


@pytest.mark.parametrize("kind,roughness,scale,rotation,z,phi", ANISOTROPIC)
def test_sharp_anisotropic_samples_follow_their_pdf_off_the_plane(kind, roughness, scale,
                                                                  rotation, z, phi):
    def params(k):
        return B.make_params(kind, 0.9, roughness, 1.5, k=k, aniso_scale=scale,
                             aniso_rotation=rotation)

    _check(params, z, phi, None, f"aniso {B.KIND_NAMES[kind]} r{roughness} x{scale} {phi}")


# (base kind, coat roughness, cos theta_o, view azimuth)
COATS = [(B.KIND_DIFFUSE, 0.05, 0.7, 2.0), (B.KIND_CONDUCTOR, 0.05, 0.4, 3.9),
         (B.KIND_DIELECTRIC, 0.1, 0.6, 5.0), (B.KIND_DIFFUSE, 0.6, 0.3, 1.2)]


@pytest.mark.parametrize("base,coat_roughness,z,phi", COATS)
def test_tilted_coat_samples_follow_their_pdf_at_any_azimuth(base, coat_roughness, z, phi):
    def params(k):
        p = B.make_params(base, (0.7, 0.5, 0.3), 0.3, 1.5, k=k, coat_weight=0.8,
                          coat_roughness=coat_roughness, coat_ior=1.6)
        return dataclasses.replace(p, coat_normal=np.tile(TILTED, (k, 1)),
                                   coat_flip=np.zeros(k))

    eta = 1.5 if base == B.KIND_DIELECTRIC else None
    _check(params, z, phi, eta, f"tilted coat {B.KIND_NAMES[base]} r{coat_roughness} {phi}")


# (base kind, base roughness, sheen roughness, cos theta_o, view azimuth)
SHEENS = [(B.KIND_DIFFUSE, 0.5, 0.05, 0.3, 0.9), (B.KIND_CONDUCTOR, 0.1, 0.4, 0.7, 2.5),
          (B.KIND_DIELECTRIC, 0.2, 0.3, 0.5, 4.4)]


@pytest.mark.parametrize("base,roughness,sheen_roughness,z,phi", SHEENS)
def test_sheen_samples_follow_their_pdf_off_the_plane(base, roughness, sheen_roughness, z, phi):
    def params(k):
        return B.make_params(base, 0.7, roughness, 1.5, k=k, sheen_weight=0.8,
                             sheen_roughness=sheen_roughness)

    eta = 1.5 if base == B.KIND_DIELECTRIC else None
    _check(params, z, phi, eta, f"sheen {sheen_roughness} over {B.KIND_NAMES[base]} {phi}")


@pytest.mark.parametrize("roughness,ior,z,phi", [(0.05, 1.5, 0.7, 1.7), (0.6, 1.5, 0.4, 3.3),
                                                 (1.0, 2.5, 0.9, 5.9)])
def test_multiscatter_specular_layer_samples_follow_their_pdf_off_the_plane(roughness, ior, z,
                                                                            phi):
    def params(k):
        return B.make_params(B.KIND_LAYERED_MS, 0.6, roughness, ior, k=k)

    _check(params, z, phi, None, f"layered_ms r{roughness} ior{ior} {phi}")
