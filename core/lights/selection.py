"""Light selection: how next-event estimation (and a light path) chooses one emitter.

Emitter rows are the scene's lamps (rows ``0..k-1``), then the emissive triangles (grouped by
material), then the world. The choice is made in two steps, each a discrete distribution built
with ``method`` (``'cdf'`` or ``'alias'``, see :mod:`core.sampling.distributions`):

1. a *light*: each lamp, each emission material (all triangles that share it form one light,
   as an emissive object would) and the world, by the strategy's weights;
2. for an emission material, one of its triangles in proportion to its power (area x luminance
   of its radiance), with the remapped random number of step 1.

Every strategy has ``choose(u, counters, p=None, n=None) -> (index, pmf)`` and ``pmf(index, p,
n)``, the probability the pdfs reported to MIS use. ``power`` chooses lights in proportion to
their estimated power (the product of the two steps is then each emitter's share of the total
power, as a single table would give); ``uniform`` gives every light that emits the same
probability. Both are a :class:`LightSelection` with a table ``select_prob`` and ignore the
receiving point. ``tree`` (:class:`TreeSelection`) chooses between the finite emitters, as one
entry, and each infinite one (suns, the world) by power, then descends a light tree
(:mod:`.tree`) from the receiving point ``p`` and its shading normal ``n``: its probabilities
depend on ``(p, n)``. All three are unbiased.
"""

from __future__ import annotations

import time

import numpy as np

from ..sampling.distributions import Segmented1D, make_distribution
from .tree import EmitterBounds, LightTree, lamp_bounds, triangle_bounds


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
    point_dependent = False

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

    def pmf(self, index, p=None, n=None):
        """Probability ``(m,)`` that :meth:`choose` returns emitter rows ``index (m,)`` (the
        table; ``p`` and ``n`` are not used)."""
        return self.select_prob[index]

    def choose(self, u_select, counters=None, p=None, n=None):
        """Choose emitters.

        Parameters
        ----------
        u_select : (n,) float
            Uniform in [0, 1): picks the light, and its remapped value the triangle.
        counters : core.integrators.base.Counters or None
            Receives the time spent and the number of discrete draws.
        p, n : ignored
            Receiving points and normals (used by :class:`TreeSelection` only).

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
        draws = light.size
        if k == 0 and self.n_groups == 1 and not self.has_world:
            # Emissive triangles of one material only (a mesh light): every draw picks one of
            # them, without the masks and scatters (the same values).
            e, pmf_tri = self.triangle_dist.pick(light, u_next)
            pmf *= pmf_tri
            if counters is not None:
                counters.distribution_s += time.perf_counter() - t0
                counters.distribution_samples += 2 * draws
            return e, pmf
        index = light.copy()
        m = np.nonzero((light >= k) & (light < k + self.n_groups))[0]
        if m.size:
            e, pmf_tri = self.triangle_dist.pick(light[m] - k, u_next[m])
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


class TreeSelection:
    """Finite emitters through a light tree from the receiving point, infinite ones by power.

    The first step chooses between the tree (all finite emitters, with their total power) and
    each sun and the world by power, independent of the receiving point, as pbrt-v4's
    ``BVHLightSampler`` does; the second descends the tree (:class:`.tree.LightTree`).
    Emitters without power are never chosen.

    Parameters
    ----------
    power : (lights,) float64
        As :class:`LightSelection`: lamps, emission materials, then the world if it emits.
    lights : core.scene.Lights
    infinite : (k,) bool
        Suns among the lamps.
    triangles : core.lights.triangles.EmissiveTriangles
    has_world : bool
    method : str
        ``'cdf'`` or ``'alias'`` (the first step).

    Attributes
    ----------
    light_dist : distribution over the tree and the infinite emitters, or None without emitters
    top_rows : (entries,) int64
        Emitter row of each first-step entry (-1: the tree).
    top_prob : (entries,) float64
    tree : core.lights.tree.LightTree or None
    steers : bool
        Whether the receiving point changes the tree's choice: False for one finite emitter or
        several whose bounds are alike (:meth:`.tree.EmitterBounds.alike`), where it chooses
        in proportion to power as :class:`PowerSelection` does.
    build_s : float
    """

    name = "tree"
    point_dependent = True

    def __init__(self, power, lights, infinite, triangles, has_world, method):
        self.n_lamps = k = len(lights)
        n_tris = triangles.emissive.size
        self.n_emitters = k + n_tris + int(has_world)
        self.world_index = k + n_tris if has_world else -1
        self.triangle_dist = None
        t0 = time.perf_counter()
        lamp_power = np.asarray(power[:k], np.float64)
        finite = np.nonzero(~infinite & (lamp_power > 0))[0]
        # An emission material's power split over its triangles as power selection splits it.
        tri_power = triangles.emit_power
        parts = [lamp_bounds(lights, finite, lamp_power[finite])]
        if n_tris:
            parts.append(triangle_bounds(triangles, k, tri_power))
        bounds = EmitterBounds.concatenate(parts)
        bounds = bounds.select(np.nonzero(bounds.power > 0)[0])
        self.tree = LightTree(bounds) if bounds.index.size else None
        # Nothing for a receiving point to steer (one emitter, or emitters whose bounds are
        # alike): the tree's choice is power selection's (core.lights.sampler uses that).
        self.steers = not bounds.alike()
        inf_rows = np.nonzero(infinite & (lamp_power > 0))[0]
        inf_power = lamp_power[inf_rows]
        if has_world and power[-1] > 0:
            inf_rows = np.append(inf_rows, self.world_index)
            inf_power = np.append(inf_power, power[-1])
        top_rows = np.concatenate([[-1] if self.tree is not None else [], inf_rows])
        top_power = np.concatenate([[bounds.power.sum()] if self.tree is not None else [],
                                    inf_power])
        self.top_rows = top_rows.astype(np.int64)
        self.light_dist = (make_distribution(top_power, method) if top_power.sum() > 0
                           else None)
        self.top_prob = (self.light_dist.pmf_table if self.light_dist is not None
                         else np.zeros(0))
        # First-step probability of every emitter row: the tree's for finite ones.
        self.entry_prob = np.zeros(self.n_emitters)
        if self.tree is not None:
            self.entry_prob[self.tree.leaf_rows] = self.top_prob[0]
        self.in_tree = np.zeros(self.n_emitters, bool)
        if self.tree is not None:
            self.in_tree[self.tree.leaf_rows] = True
        inf_entry = self.top_rows >= 0
        self.entry_prob[self.top_rows[inf_entry]] = self.top_prob[inf_entry]
        self.build_s = time.perf_counter() - t0

    def pmf(self, index, p=None, n=None):
        """Probability ``(m,)`` that :meth:`choose` from receiving points ``p (m, 3)`` with
        shading normals ``n (m, 3)`` (or None) returns emitter rows ``index (m,)``. ``p`` may be
        None when every row is infinite (the world, suns)."""
        out = self.entry_prob[index]
        if self.tree is not None and p is not None:
            finite = self.in_tree[index]
            out = out * np.where(finite, self.tree.pmf(index, p, n), 1.0)
        return out

    def choose(self, u_select, counters=None, p=None, n=None):
        """Choose emitters from receiving points.

        Parameters
        ----------
        u_select : (m,) float
            Uniform in [0, 1): picks the first-step entry, and its remapped value the path down
            the tree.
        counters : core.integrators.base.Counters or None
        p : (m, 3) float64
            Receiving points.
        n : (m, 3) float64 or None
            Their shading normals.

        Returns
        -------
        index : (m,) int64
        pmf : (m,) float64
            Equal to ``pmf(index, p, n)``.
        """
        t0 = time.perf_counter()
        entry, pmf, u_next = self.light_dist.sample(u_select)
        index = self.top_rows[entry]
        t = np.nonzero(index < 0)[0]
        if t.size == index.size:
            # Only finite emitters (no sun, no world): every row descends, no gathers.
            index, pmf_tree = self.tree.choose(u_next, p, n)
            pmf = pmf * pmf_tree
        elif t.size:
            e, pmf_tree = self.tree.choose(u_next[t], p[t], None if n is None else n[t])
            index[t] = e
            pmf[t] = pmf[t] * pmf_tree
        if counters is not None:
            counters.distribution_s += time.perf_counter() - t0
            counters.distribution_samples += entry.size + t.size
        return index, pmf


SELECTIONS = {cls.name: cls for cls in (PowerSelection, UniformSelection, TreeSelection)}
