"""Light selection: how next-event estimation (and a light path) chooses one emitter.

Emitter rows are the scene's lamps (rows ``0..k-1``), then the emissive triangles (grouped by
material), then the world. The choice is made in two steps, each a discrete distribution built
with ``method`` (``'cdf'`` or ``'alias'``, see :mod:`core.sampling.distributions`):

1. a *light*: each lamp, each emission material (all triangles that share it form one light,
   as an emissive object would) and the world, by the strategy's weights;
2. for an emission material, one of its triangles in proportion to its power (area x luminance
   of its radiance), with the remapped random number of step 1.

Every strategy is a :class:`LightSelection`: ``choose(u, counters) -> (index, pmf)`` and the
table ``select_prob`` of each emitter's probability, which the pdfs reported to MIS use.
``power`` chooses lights in proportion to their estimated power (the product of the two steps is
then each emitter's share of the total power, as a single table would give); ``uniform`` gives
every light that emits the same probability. Both are unbiased. A light tree (pbrt-v4's
``BVHLightSampler``) would be one more subclass whose probabilities depend on the receiving
point: it would take ``p`` in ``choose`` and give ``select_prob`` per point.
"""

from __future__ import annotations

import time

import numpy as np

from ..sampling.distributions import Segmented1D, make_distribution


class LightSelection:
    """Choose emitters in two steps by per-light ``weights`` (see the module docstring).

    Parameters
    ----------
    power : (lights,) float64
        Estimated power per light: lamps, emission materials, then the world if it emits.
    n_lamps : int
    triangles : core.lights.triangles.EmissiveTriangles
    has_world : bool
    method : str
        ``'cdf'`` or ``'alias'``.

    Attributes
    ----------
    light_dist : distribution over lights, or None without emitters
    triangle_dist : core.sampling.distributions.Segmented1D or None
        One segment per emission material, over its triangles' power.
    select_prob : (n_emitters,) float64
        Probability that :meth:`choose` returns each emitter row.
    build_s : float
        Seconds spent building the distributions.
    """

    name = None

    @staticmethod
    def weights(power):
        """Selection weights of lights with estimated ``power``."""
        raise NotImplementedError

    def __init__(self, power, n_lamps, triangles, has_world, method):
        self.n_lamps = k = n_lamps
        self.n_groups = triangles.n_groups
        self.has_world = has_world
        self.world_index = k + triangles.emissive.size if has_world else -1
        n_tris = triangles.emissive.size
        t0 = time.perf_counter()
        weights = self.weights(power)
        self.light_dist = make_distribution(weights, method) if weights.size else None
        self.triangle_dist = (Segmented1D(triangles.emit_power,
                                          np.append(triangles.group_start, n_tris), method)
                              if n_tris else None)
        self.build_s = time.perf_counter() - t0
        if self.light_dist is not None:
            light_pmf = self.light_dist.pmf_table
            tri_prob = (light_pmf[k + triangles.emit_group] * self.triangle_dist.pmf_table
                        if n_tris else np.zeros(0))
            self.select_prob = np.concatenate([light_pmf[:k], tri_prob,
                                               light_pmf[k + self.n_groups:]])
        else:
            self.select_prob = np.zeros(0)

    def choose(self, u_select, counters=None):
        """Choose emitters.

        Parameters
        ----------
        u_select : (n,) float
            Uniform in [0, 1): picks the light, and its remapped value the triangle.
        counters : core.integrators.base.Counters or None
            Receives the time spent and the number of discrete draws.

        Returns
        -------
        index : (n,) int64
            Emitter rows.
        pmf : (n,) float64
            Their selection probabilities (``select_prob[index]``).
        """
        t0 = time.perf_counter()
        k = self.n_lamps
        light, pmf, u_next = self.light_dist.sample(u_select)
        index = light.copy()
        draws = light.size
        m = np.nonzero((light >= k) & (light < k + self.n_groups))[0]
        if m.size:
            e, pmf_tri, _ = self.triangle_dist.sample(light[m] - k, u_next[m])
            index[m] = k + e
            pmf[m] = pmf[m] * pmf_tri
            draws += m.size
        if self.has_world:
            index[light == k + self.n_groups] = self.world_index
        if counters is not None:
            counters.distribution_s += time.perf_counter() - t0
            counters.distribution_samples += draws
        return index, pmf


class PowerSelection(LightSelection):
    """Lights in proportion to their estimated power."""

    name = "power"

    @staticmethod
    def weights(power):
        return power


class UniformSelection(LightSelection):
    """Every light that emits with the same probability."""

    name = "uniform"

    @staticmethod
    def weights(power):
        return (power > 0).astype(np.float64)


SELECTIONS = {cls.name: cls for cls in (PowerSelection, UniformSelection)}
