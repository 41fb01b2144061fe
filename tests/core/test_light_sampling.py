"""Light sampling: NEE's directions follow the density NEE assigns to them, selection follows power.

For every non-delta emitter, directions drawn by ``LightSampler.sample`` from a fixed point are
histogrammed in ``(cos theta, phi)`` cells of a frame whose axis points at the light, so that
even a small light spans the histogram (the zone ``cos theta >= z0`` holds the light's solid
angle and a margin around it). The expected count of a cell is the integral of the density that
the *ray* side of MIS uses for the same direction (``hit_shapes`` for spheres, area lights and
sun disks; Embree + ``triangle_pdf`` for emissive triangles; ``world_radiance`` for the world).
The chi-square therefore checks at once that the samples follow that density, that it is zero
off the light (a sample in a cell of density zero fails), and that it integrates to one over the
light's solid angle (the cell masses must sum to one within the quadrature's 1e-3); a separate
exact check requires every sampled direction to have positive density. ``test_lights.py`` checks
that the two pdfs agree pointwise and that NEE's irradiance is right; this file checks the shape.

Tolerances: alpha = 1e-3 per chi-square test (helpers), n = 2e5 samples.
"""

from __future__ import annotations

import numpy as np
import pytest

from sampling_lab.core import lights as L
from sampling_lab.core.prepare import prepare
from sampling_lab.core.scene import Camera, Lights, Materials, Scene
from sampling_lab.core.scenes import look_at
from tests.helpers import (
    chi_square_counts,
    chi_square_test,
    directions_from_z_phi,
    histogram_2d,
    integrate_solid_angle,
    z_phi_from_directions,
)

N = 200_000
RES = (16, 32)      # (cos theta, phi) cells over the zone that holds the light
SUBDIV = 16         # quadrature sub-cells per cell side
REFINE = 4          # finer sub-cells in the cells that the light's edge cuts
P_WORLD = np.array([0.1, -0.2, 0.0])


def make_scene(lights=None, tris=None, emissions=((0.0, 0.0, 0.0),), tri_material=None,
               world=(0.0, 0.0, 0.0)):
    """A scene of just the given emitters (its camera is never used)."""
    if tris is None:
        v, f = np.zeros((0, 3)), np.zeros((0, 3), np.int32)
    else:
        v, f = tris
    f = np.asarray(f, np.int32).reshape(-1, 3)
    material = (np.zeros(len(f), np.int32) if tri_material is None
                else np.asarray(tri_material, np.int32))
    names = [f"M{i}" for i in range(len(emissions))]
    mats = Materials.from_lists(names, [(0.5, 0.5, 0.5)] * len(emissions), emissions)
    cam = Camera(look_at((0, -5, 0), (0, 0, 0)), 8, 8)
    return Scene(v, f, material, mats, lights or Lights.empty(), cam, world_color=world)


def frame_around(axis):
    """Rows (s, t, a) of an orthonormal frame whose third axis is ``axis``."""
    a = np.asarray(axis, np.float64)
    a = a / np.linalg.norm(a)
    helper = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    s = np.cross(helper, a)
    s /= np.linalg.norm(s)
    return np.stack([s, np.cross(a, s), a])


def cone_zone(cos_max, nz=RES[0]):
    """Zone and resolution whose first row lies just outside a cone of ``cos_max``.

    The row boundary falls exactly on the cone's edge, so the midpoint quadrature of a density
    that is constant inside the cone is exact, and a sample outside the cone lands in a row of
    probability zero.
    """
    z0 = cos_max - (1.0 - cos_max) / nz
    return (z0, 1.0), (nz + 1, RES[1])


def polygon_zone(p, axis, boundary):
    """Zone around ``axis`` holding the directions from ``p`` to the ``boundary`` points.

    The light's directions fill the region bounded by the directions to its boundary, so their
    smallest ``cos`` to the axis bounds the light; a 10 % margin of ``1 - cos`` leaves cells of
    probability zero around it.
    """
    d = np.asarray(boundary, np.float64) - p
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    cos_min = float((d @ (axis / np.linalg.norm(axis))).min())
    return (1.0 - 1.1 * (1.0 - cos_min), 1.0), RES


def nee_directions(prep, p, frame):
    """``sample_fn`` for the checker: NEE directions from ``p`` in the light's frame."""
    def sample(u):
        n = len(u)
        pts = np.broadcast_to(p, (n, 3)).astype(np.float64)
        u_sel = np.full(n, 0.5)  # one emitter: selection is certain
        wi, dist, radiance, pdf, delta, _ = prep.lights.sample(pts, u_sel, u)
        assert not delta.any(), "a non-delta emitter was sampled as delta"
        assert np.all(pdf > 0), f"{np.count_nonzero(pdf <= 0)} failed NEE samples"
        return wi @ frame.T
    return sample


def shape_pdf(prep, p, frame):
    """Density that ``hit_shapes`` (the BSDF-sampling side of MIS) assigns to directions."""
    def pdf(w_local):
        d = w_local @ frame
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        o = np.broadcast_to(p, d.shape).astype(np.float64)
        out = np.zeros(len(d))
        for rows, _, pdf_hit in prep.lights.hit_shapes(o, d, np.full(len(d), np.inf),
                                                       camera=False):
            out[rows] += pdf_hit
        return out
    return pdf


def triangle_hit_pdf(prep, p, frame):
    """Density that a ray hitting an emissive triangle gets from ``triangle_pdf``."""
    def pdf(w_local):
        d = w_local @ frame
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        o = np.broadcast_to(p, d.shape).astype(np.float64)
        hits = prep.accel.intersect(o, d)
        out = np.zeros(len(d))
        ok = hits.prim >= 0  # triangle_pdf is defined for hit triangles only
        prim = hits.prim[ok]
        cos = np.einsum("ij,ij->i", d[ok], prep.tri_normal[prim])
        out[ok] = prep.lights.triangle_pdf(prim, o[ok], hits.t[ok], cos)
        return out
    return pdf


def cell_masses(pdf_fn, zone, res):
    """Probability of each ``(cos theta, phi)`` cell under a solid-angle density with edges.

    Midpoint quadrature on ``SUBDIV`` x ``SUBDIV`` sub-cells, redone on ``REFINE`` times finer
    sub-cells in every cell that the light's edge crosses (some sub-cells lit, some not) or
    touches (an unlit cell next to a lit one), so edge cells get accurate expectations.

    Returns
    -------
    mass : (nz, nphi) float64
    rim : (nz, nphi) bool
        Cells next to lit cells whose quadrature found no light: the edge may still clip them
        by less than the quadrature resolves.
    """
    (z0, z1), (p0, p1) = zone, (0.0, 2 * np.pi)
    nz, nphi = res

    def integrate(cells, k):
        # Sub-cell midpoints of the given cells, k x k each.
        i, j = cells[:, 0], cells[:, 1]
        f = (np.arange(k) + 0.5) / k
        z = z0 + (i[:, None, None] + f[None, :, None]) * ((z1 - z0) / nz)
        ph = p0 + (j[:, None, None] + f[None, None, :]) * ((p1 - p0) / nphi)
        z, ph = np.broadcast_arrays(z, ph)
        dens = pdf_fn(directions_from_z_phi(np.stack([z.ravel(), ph.ravel()], -1)))
        dens = dens.reshape(len(cells), k * k)
        return dens.mean(axis=1) * ((z1 - z0) / nz) * ((p1 - p0) / nphi), (dens > 0).mean(1)

    all_cells = np.argwhere(np.ones(res, bool))
    mass, lit = (a.reshape(res) for a in integrate(all_cells, SUBDIV))
    near = np.zeros(res, bool)
    for dz in (-1, 0, 1):
        for dp in (-1, 0, 1):
            shifted = np.roll(lit > 0, dp, axis=1)  # phi wraps around
            if dz > 0:
                shifted = np.concatenate([np.zeros((dz, nphi), bool), shifted[:-dz]])
            elif dz < 0:
                shifted = np.concatenate([shifted[-dz:], np.zeros((-dz, nphi), bool)])
            near |= shifted
    edge = ((lit > 0) & (lit < 1)) | ((lit == 0) & near)
    cells = np.argwhere(edge)
    if len(cells):
        m, _ = integrate(cells, SUBDIV * REFINE)
        mass[edge] = m
    return mass, edge & (mass == 0)


def chi_square_light(samples, pdf_fn, zone, res, what):
    """Chi-square of NEE directions (light frame) against the MIS density of the same light.

    Besides the chi-square, every sample must have a positive density (an exact support check),
    and no sample may fall in a cell away from the light.
    """
    assert np.all(np.isfinite(samples)), f"{what}: non-finite directions"
    dens = pdf_fn(samples)
    assert np.all(dens > 0), f"{what}: {np.count_nonzero(dens <= 0)} NEE directions miss the light"
    counts, outside = histogram_2d(z_phi_from_directions(samples), (zone, (0.0, 2 * np.pi)), res)
    assert outside == 0, f"{what}: {outside} samples outside the zone {zone}"
    mass, rim = cell_masses(pdf_fn, zone, res)
    assert abs(mass.sum() - 1.0) < 1e-3, f"{what}: the density integrates to {mass.sum():.6f}"
    # A rim cell's count joins the lit neighbour with the largest mass: the light's edge clips
    # the rim cell by less than the quadrature resolves (the support check above is exact).
    counts = counts.astype(np.float64)
    for i, j in np.argwhere(rim & (counts > 0)):
        nb = [((i + a), (j + b) % res[1]) for a in (-1, 0, 1) for b in (-1, 0, 1)
              if 0 <= i + a < res[0]]
        best = max(nb, key=lambda c: mass[c])
        counts[best] += counts[i, j]
        counts[i, j] = 0
    return chi_square_counts(counts.ravel(), len(samples) * mass.ravel(), what=what)


def check_light(prep, p, axis, zone, res, pdf_factory, seed, what, pdf_override=None):
    frame = frame_around(axis)
    rng = np.random.default_rng(seed)
    samples = nee_directions(prep, p, frame)(rng.random((N, 2)))
    pdf_fn = pdf_factory(prep, p, frame)
    return chi_square_light(samples, pdf_override or pdf_fn, zone, res, what)


# --------------------------------------------------------------------------------------------
# Directions follow the MIS density, which integrates to one over the light
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("r_over_d", [0.5, 0.01])
def test_sphere_light_directions_match_hit_pdf(r_over_d):
    centre = P_WORLD + 2.0 * np.array([0.3, 0.2, 1.0]) / np.linalg.norm([0.3, 0.2, 1.0])
    lights = L.point_light(centre, (1, 1, 1), 50.0, radius=2.0 * r_over_d)
    prep = prepare(make_scene(lights))
    zone, res = cone_zone(np.sqrt(1.0 - r_over_d**2))
    check_light(prep, P_WORLD, centre - P_WORLD, zone, res, shape_pdf, seed=11,
                what=f"sphere light r/d={r_over_d}")


@pytest.mark.parametrize("angle_deg", [0.53, 20.0])
def test_sun_disk_directions_match_hit_pdf(angle_deg):
    travel = np.array([0.2, 0.1, -1.0])
    lights = L.sun_light(travel, (1, 1, 1), 3.0, np.radians(angle_deg))
    prep = prepare(make_scene(lights))
    zone, res = cone_zone(np.cos(0.5 * np.radians(angle_deg)))
    check_light(prep, P_WORLD, -travel, zone, res, shape_pdf, seed=12,
                what=f"sun angle={angle_deg} deg")


def _area_case(case):
    """(lights, boundary points) of the area light cases, facing ``P_WORLD``."""
    if case == "rect":
        m = look_at((0.2, 0.1, 1.2), (0.0, 0.1, -3.0))
        shape, sx, sy = "RECTANGLE", 0.8, 0.5
    elif case == "rect_grazing":
        # Seen 80 degrees off its normal: the pdf d^2 / (cos A) varies strongly across it.
        c = np.array([1.2, 0.3, 0.9])
        v = (P_WORLD - c) / np.linalg.norm(P_WORLD - c)
        side = np.cross(v, (0.0, 1.0, 0.0))
        side /= np.linalg.norm(side)
        normal = np.cos(np.radians(80)) * v + np.sin(np.radians(80)) * side
        m = look_at(c, c + normal, up=(0, 1, 0))
        shape, sx, sy = "RECTANGLE", 1.0, 0.6
    elif case == "ellipse":
        m = look_at((-0.4, 0.3, 0.9), (0.3, -0.5, -2.0))
        m[:3, 0] *= 1.5  # object scale stretches the disk into an ellipse
        shape, sx, sy = "ELLIPSE", 0.7, 0.4
    else:
        m = look_at((0.0, 0.0, 0.3), (0.0, 0.0, -1.0), up=(0, 1, 0))  # close, large: wide angle
        shape, sx, sy = "DISK", 0.8, 0.8
    lights = L.area_light(m, shape, sx, sy, (1, 1, 1), 30.0)
    c, ax, ay = lights.position[0], lights.axis_x[0], lights.axis_y[0]
    if shape in ("RECTANGLE", "SQUARE"):
        boundary = [c + sx_ * ax / 2 + sy_ * ay / 2 for sx_ in (-1, 1) for sy_ in (-1, 1)]
    else:
        t = np.linspace(0, 2 * np.pi, 721)
        boundary = c + np.cos(t)[:, None] * ax / 2 + np.sin(t)[:, None] * ay / 2
    return lights, np.asarray(boundary)


@pytest.mark.parametrize("case", ["rect", "rect_grazing", "ellipse", "disk_close"])
def test_area_light_directions_match_hit_pdf(case):
    lights, boundary = _area_case(case)
    normal = lights.direction[0]
    assert (P_WORLD - lights.position[0]) @ normal > 0, "test setup: light must face the point"
    prep = prepare(make_scene(lights))
    axis = lights.position[0] - P_WORLD
    zone, res = polygon_zone(P_WORLD, axis, boundary)
    check_light(prep, P_WORLD, axis, zone, res, shape_pdf, seed=13, what=f"area light {case}")


TRI = np.array([[-0.5, -0.4, 1.0], [0.7, -0.2, 1.3], [0.1, 0.6, 0.9]])


@pytest.mark.parametrize("faces, offset", [
    ([0, 1, 2], (0.0, 0.0, 0.0)),
    ([0, 2, 1], (0.0, 0.0, 0.0)),           # seen from its back face: it emits from both
    ([0, 1, 2], (3.0e4, -2.0e4, 1.0e4)),    # far from the origin: the recentred frame
], ids=["front", "back", "far"])
def test_emissive_triangle_directions_match_triangle_pdf(faces, offset):
    offset = np.asarray(offset)
    scene = make_scene(tris=(TRI + offset, [faces]), emissions=[(2.0, 2.0, 2.0)])
    prep = prepare(scene)
    p = P_WORLD + offset - prep.shift  # the receiving point in the prepared (local) frame
    verts = prep.tri_v0[0] + np.stack([np.zeros(3), prep.tri_e1[0], prep.tri_e2[0]])
    axis = verts.mean(axis=0) - p
    zone, res = polygon_zone(p, axis, verts)
    check_light(prep, p, axis, zone, res, triangle_hit_pdf, seed=14,
                what=f"emissive triangle {faces} at {offset}")


def test_world_directions_match_world_pdf():
    prep = prepare(make_scene(world=(0.3, 0.4, 0.5)))
    check_light(prep, P_WORLD, (0.0, 0.0, 1.0), (-1.0, 1.0), (20, 40),
                lambda prep_, p, frame: (lambda w: prep_.lights.world_radiance(w @ frame)[1]),
                seed=15, what="world")


def test_direction_check_rejects_uniform_solid_angle_density_for_an_area_light():
    """The binning resolves the shape of the density inside the light, not just its support.

    Area sampling has density d^2 / (cos A area); a light seen up close and at an angle makes
    that far from uniform over its solid angle, and the checker must notice if the claimed pdf
    were the (correctly normalised) uniform density instead.
    """
    lights, boundary = _area_case("rect_grazing")
    prep = prepare(make_scene(lights))
    axis = lights.position[0] - P_WORLD
    zone, res = polygon_zone(P_WORLD, axis, boundary)
    frame = frame_around(axis)
    inside = shape_pdf(prep, P_WORLD, frame)
    solid_angle = integrate_solid_angle(lambda w: (inside(w) > 0).astype(float), zone, (512, 512))
    with pytest.raises(AssertionError, match="chi-square"):
        check_light(prep, P_WORLD, axis, zone, res, shape_pdf, seed=13, what="uniform claim",
                    pdf_override=lambda w: (inside(w) > 0) / solid_angle)


# --------------------------------------------------------------------------------------------
# Light selection
# --------------------------------------------------------------------------------------------


def _mixed_scene():
    """Every kind of emitter, each with its own hue so a sample's radiance tells its source."""
    spot_pos = np.array([-1.0, 0.5, 2.0])
    rect = look_at((0.8, -0.3, 1.5), (0.8, -0.3, -3.0), up=(0, 1, 0))
    disk = look_at((-0.6, -0.8, 1.2), (0.0, 0.0, -2.0))
    rows = [
        L.point_light((0.5, 0.3, 2.0), (1.0, 0.0, 0.0), 60.0, name="point"),
        L.point_light((-0.3, 0.9, 1.7), (0.0, 1.0, 0.0), 40.0, radius=0.2, name="sphere"),
        L.point_light(spot_pos, (0.0, 0.0, 1.0), 80.0, name="spot",
                      spot_direction=P_WORLD - spot_pos, spot_size=np.radians(50),
                      spot_blend=0.3),
        L.area_light(rect, "RECTANGLE", 0.6, 0.4, (1.0, 1.0, 0.0), 30.0, name="rect"),
        L.area_light(disk, "DISK", 0.5, 0.5, (1.0, 0.0, 1.0), 25.0, name="disk"),
        L.sun_light((0.3, 0.2, -1.0), (0.0, 1.0, 1.0), 0.3, np.radians(5), name="sun disk"),
        L.sun_light((-0.2, 0.4, -1.0), (1.0, 0.5, 0.0), 0.3, name="sun"),
    ]
    tris = np.array([[-0.5, -0.4, 1.0], [0.7, -0.2, 1.3], [0.1, 0.6, 0.9],
                     [1.0, 1.0, 0.5], [1.5, 1.2, 0.8], [1.1, 1.6, 0.4],
                     [-2.0, 0.0, -1.0], [-2.0, 1.0, -1.0], [-1.0, 0.0, -1.0]])
    faces = [[0, 1, 2], [3, 4, 5], [6, 7, 8]]
    emissions = [(0.2, 0.5, 1.0), (3.0, 0.6, 1.5), (0.0, 0.0, 0.0)]  # third: not an emitter
    world = (0.03, 0.02, 0.01)
    scene = make_scene(Lights.concat(rows), tris=(tris, faces), emissions=emissions,
                       tri_material=[0, 1, 2], world=world)
    hues = [r.radiance[0] for r in rows] + [np.array(e) for e in emissions[:2]] + [world]
    names = [r.names[0] for r in rows] + ["triangle 0", "triangle 1", "world"]
    delta = [True, False, True, False, False, False, True, False, False, False]
    return scene, np.array(hues, np.float64), names, np.array(delta)


def _classify(radiance, hues):
    """Index of the emitter whose hue (chromaticity) the sampled radiance has."""
    h = hues / hues.sum(axis=1, keepdims=True)
    r = radiance / radiance.sum(axis=1, keepdims=True)
    dist = np.abs(r[:, None, :] - h[None, :, :]).sum(axis=2)
    return dist.argmin(axis=1), dist.min(axis=1)


def test_light_selection_frequencies_match_select_prob():
    scene, hues, names, delta = _mixed_scene()
    prep = prepare(scene)
    ls = prep.lights
    assert ls.n_emitters == len(hues)
    np.testing.assert_array_equal(ls.delta, delta)
    assert np.all(ls.select_prob > 0.01), "test setup: every emitter must be chosen often"
    assert abs(ls.select_prob.sum() - 1.0) < 1e-12

    rng = np.random.default_rng(21)
    p = np.broadcast_to(P_WORLD - prep.shift, (N, 3)).astype(np.float64)
    wi, dist, radiance, pdf, is_delta, _ = ls.sample(p, rng.random(N), rng.random((N, 2)))
    assert np.all(pdf > 0) and np.all(radiance.sum(axis=1) > 0), "test setup: all emitters lit"
    which, miss = _classify(radiance, hues)
    # Emission is stored in float32: hues match to its precision, and are far apart.
    h = hues / hues.sum(axis=1, keepdims=True)
    gaps = np.abs(h[:, None] - h[None]).sum(axis=2) + np.eye(len(h))
    assert gaps.min() > 0.05
    assert miss.max() < 1e-6, "a sample's radiance matches no emitter's colour"
    np.testing.assert_array_equal(is_delta, delta[which])
    # Delta emitters report their selection probability as the pdf.
    np.testing.assert_allclose(pdf[is_delta], ls.select_prob[which[is_delta]], rtol=1e-12)
    chi_square_test(which, ls.select_prob, what="light selection")


def test_selection_check_rejects_uniform_selection():
    scene, hues, _, _ = _mixed_scene()
    prep = prepare(scene)
    rng = np.random.default_rng(21)
    p = np.broadcast_to(P_WORLD - prep.shift, (N, 3)).astype(np.float64)
    _, _, radiance, _, _, _ = prep.lights.sample(p, rng.random(N), rng.random((N, 2)))
    which, _ = _classify(radiance, hues)
    with pytest.raises(AssertionError, match="chi-square"):
        chi_square_test(which, np.full(len(hues), 1.0 / len(hues)), what="uniform claim")
