"""Primary sample space: Markov chains over vectors of uniform numbers (Kelemen et al. 2002).

A path is a deterministic function of the numbers its :class:`core.sampling.stream.SampleStream`
gives it, so a vector ``u`` in ``[0, 1)^D`` *is* a path, and its contribution ``L(u)`` (RGB) is a
function on the unit cube. Metropolis-Hastings over that cube samples vectors with density
``f(u) / b``, ``f`` the luminance of ``L`` and ``b = integral of f``; a proposal is

- a *large step* (probability ``large_step_probability``): every number fresh and uniform;
- a *small step*: every number moved by Kelemen's exponential perturbation, ``u +- dv`` with
  ``dv = s2 exp(-log(s2 / s1) t)``, ``t`` uniform (so ``dv`` is log-uniform on ``[s1, s2]``),
  the sign equally likely, wrapped around ``[0, 1)`` (a torus).

Both are symmetric (the density of ``u -> v`` equals that of ``v -> u``), so the acceptance is
Metropolis' ``min(1, f(v) / f(u))``. The small step comes as a warp triple:
:func:`sample_small_step`, :func:`small_step_pdf`, :func:`invert_small_step`.

:class:`Chains` holds a batch of chains struct-of-arrays (one row per chain) and
:func:`metropolis_step` mutates them all at once, returning Veach's expected-value splats (the
proposal weighted by the acceptance ``a``, the current state by ``1 - a``). Chains are evaluated
through :class:`PrimarySampleStream`, which hands an integrator the chain's numbers dimension by
dimension. The chains' own random numbers (proposals, acceptance) come from a
``numpy.random.Generator`` seeded by (seed, batch, pass) (:func:`chain_random`); bootstrap
vectors are a hash of (seed, index, dimension) (:func:`uniform_vectors`), so any of them can be
rebuilt from its index. Nothing depends on the thread count.
"""

from __future__ import annotations

import numpy as np

from .stream import SampleStream, hash_u32, u32_to_unit_float

# Kelemen's perturbation range: the smallest and largest move of a small step.
S1 = 1.0 / 1024.0
S2 = 1.0 / 64.0

# Rec. 709 luminance: the scalar target f of an RGB contribution.
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])

# Dimensions a chain's vectors grow by at least (two bounces of the path tracer).
GROW_STEP = 14

# The number just below one: a wrapped value never reaches 1.
_BELOW_ONE = np.nextafter(1.0, 0.0)


def luminance(rgb):
    """``f (n,)`` of contributions ``rgb (n, 3)``: positive wherever any channel is (the weights
    are all positive), so no light is lost to a zero target."""
    w = LUMINANCE
    return w[0] * rgb[:, 0] + w[1] * rgb[:, 1] + w[2] * rgb[:, 2]


def _wrap(v):
    """``v mod 1`` in ``[0, 1)`` (``v`` is modified): a value just below 0 wraps to ``1 - tiny``,
    which may round to 1.0, the point 0 of the torus."""
    v -= np.floor(v)
    v[v >= 1.0] = 0.0
    return v


def sample_small_step(u, xi, s1=S1, s2=S2):
    """Kelemen's small step of every number of ``u``.

    Parameters
    ----------
    u : (...) float64
        Current numbers, in ``[0, 1)``.
    xi : (...) float64
        Uniform numbers in ``[0, 1)``: below 1/2 adds, above subtracts; the rest of it (rescaled
        to ``[0, 1)``) sets the size ``dv = s2 (s1 / s2)^t``.

    Returns
    -------
    (...) float64
        Moved numbers, in ``[0, 1)``.
    """
    sign = np.where(xi < 0.5, 1.0, -1.0)
    t = 2.0 * xi
    t -= sign < 0  # [0, 1) on both halves
    t *= -np.log(s2 / s1)
    dv = np.exp(t, out=t)
    dv *= s2 * sign
    dv += u
    return _wrap(dv)


def small_step_pdf(u, v, s1=S1, s2=S2):
    """Density of :func:`sample_small_step` moving ``u`` to ``v`` (per number, on the torus).

    The move's size has density ``1 / (dv log(s2 / s1))`` on ``[s1, s2]`` and either sign with
    probability 1/2; ``s2 < 1/2``, so only the shorter way round can be a move. The distance is
    computed from ``|u - v|``, which is the same number both ways: the density is exactly
    symmetric.
    """
    d = np.abs(np.asarray(v, np.float64) - np.asarray(u, np.float64))
    d = np.minimum(d, 1.0 - d)
    inside = (d >= s1) & (d <= s2)
    return np.where(inside, 0.5 / (np.maximum(d, s1) * np.log(s2 / s1)), 0.0)


def invert_small_step(u, v, s1=S1, s2=S2):
    """The ``xi`` for which :func:`sample_small_step` moves ``u`` to ``v`` (NaN where no small
    step does)."""
    u, v = np.asarray(u, np.float64), np.asarray(v, np.float64)
    up = v - u
    up = np.where(up < 0.0, up + 1.0, up)  # distance going up, in [0, 1)
    down = 1.0 - up
    add = up <= 0.5
    dv = np.where(add, up, down)
    with np.errstate(divide="ignore"):
        t = np.log(s2 / np.maximum(dv, 1e-300)) / np.log(s2 / s1)
    xi = np.where(add, 0.5 * t, 0.5 + 0.5 * t)
    ok = (dv >= s1 * (1 - 1e-12)) & (dv <= s2 * (1 + 1e-12))
    return np.where(ok, np.clip(xi, 0.0, _BELOW_ONE), np.nan)


def uniform_vectors(seed, index, dims, first=0):
    """Uniform numbers ``(k, dims)`` in ``[0, 1)``: dimensions ``first .. first + dims - 1`` of
    the vectors of the integers ``index (k,)``, a hash of (seed, index, dimension), so bootstrap
    vector ``i`` can be rebuilt, or extended, from ``i`` alone."""
    index = np.asarray(index, np.int64)
    key = hash_u32(np.uint32(int(seed) & 0xFFFFFFFF) ^ np.uint32(0x6A09E667))
    row = hash_u32((index & 0xFFFFFFFF).astype(np.uint32) ^ key)
    row = hash_u32(row ^ (index >> 32).astype(np.uint32) ^ np.uint32(0xBB67AE85))
    dim = hash_u32(np.arange(first, first + dims, dtype=np.uint32) * np.uint32(0x9E3779B9)
                   + np.uint32(0x3C6EF372))
    return u32_to_unit_float(hash_u32(row[:, None] ^ dim[None, :]))


def chain_random(seed, *keys):
    """The random generator of one batch of chains in one pass: a function of ``(seed, *keys)``
    alone (NumPy's PCG64 through a ``SeedSequence``), never of threads or timing."""
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence([int(seed), *map(int,
                                                                                     keys)])))


def propose(u, rng, large_step_probability):
    """A proposal for every chain: ``(v (k, D), large (k,) bool)``; ``large`` rows got fresh
    uniform numbers, the others a small step of every number."""
    k, dims = u.shape
    large = rng.random(k) < large_step_probability
    xi = rng.random((k, dims))
    v = sample_small_step(u, xi)
    if large.any():
        v[large] = rng.random((int(large.sum()), dims))
    return v, large


def acceptance(f_current, f_proposed):
    """Metropolis' ``min(1, f' / f)`` ``(k,)`` for symmetric proposals (1 where the current
    target is zero, which a chain started by :func:`resample` never has)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        a = np.where(f_current > 0, f_proposed / np.where(f_current > 0, f_current, 1.0), 1.0)
    return np.clip(np.nan_to_num(a, nan=0.0, posinf=1.0), 0.0, 1.0)


def normalisation(f):
    """``(b, standard error)`` of the bootstrap targets ``f (n,)``: ``b``, their mean, is an
    unbiased estimate of ``integral of f`` over the unit cube (the vectors are uniform)."""
    f = np.asarray(f, np.float64)
    b = float(f.mean()) if f.size else 0.0
    se = float(f.std(ddof=1) / np.sqrt(f.size)) if f.size > 1 else float("nan")
    return b, se


def resample(f, count, rng):
    """Indices ``(count,)`` drawn with replacement in proportion to ``f (n,)`` (importance
    resampling of bootstrap samples); None if ``f`` is zero everywhere."""
    total = float(np.sum(f))
    if not total > 0:
        return None
    cdf = np.cumsum(f) / total
    picks = np.searchsorted(cdf, rng.random(count), side="right")
    return np.minimum(picks, f.size - 1)


class Chains:
    """A batch of Markov chains, one row each.

    Only the dimensions some path has read are stored (``u`` has ``width`` columns): a
    dimension no path has read is, for every chain, an independent uniform number that the
    target ignores, so it is drawn when a path first reads it (:meth:`proposal_columns`), as
    pbrt-v3's ``MLTSampler`` creates its numbers on first use.

    Attributes
    ----------
    u : (k, width) float64
        Primary numbers of each chain's current state, the dimensions read so far.
    L : (k, 3) float64
        Its contribution (RGB).
    f : (k,) float64
        Its target, ``luminance(L)`` (positive).
    key : (k,) int64
        Where its contribution goes (the film pixel).
    accepted, proposed : int
        Counts of accepted and proposed mutations.
    """

    def __init__(self, u, L, key):
        self.u = np.asarray(u, np.float64)
        self.L = np.asarray(L, np.float64)
        self.f = luminance(self.L)
        self.key = np.asarray(key, np.int64)
        self.accepted = 0
        self.proposed = 0

    def __len__(self):
        return self.f.size

    @property
    def width(self):
        return self.u.shape[1]

    def proposal_columns(self, width, rows, large, rng):
        """Grow the chains to ``width`` dimensions; the new columns ``(m, width - old)`` of the
        proposals of the chains ``rows`` (None: all).

        Every chain's new numbers are fresh uniforms (what they would be after any number of
        symmetric steps from a uniform start, since no target has read them); the proposal's
        are the mutation of them that the proposal's kind makes (a fresh uniform for a large
        step, a small step otherwise): together, the same joint law as if every dimension had
        been stored and mutated all along."""
        extra = width - self.width
        current = rng.random((len(self), extra))
        self.u = np.concatenate([self.u, current], axis=1)
        mine = current if rows is None else current[rows]
        moved = sample_small_step(mine.copy(), rng.random(mine.shape))
        if large.any():
            moved[large] = rng.random((int(large.sum()), extra))
        return moved


class Proposal:
    """The proposed vectors of one mutation ``(m, width)``, grown with the chains on demand
    (:meth:`grow`, which :class:`PrimarySampleStream` calls)."""

    def __init__(self, chains, rows, v, large, rng):
        self.chains, self.rows, self.v, self.large, self.rng = chains, rows, v, large, rng

    def grow(self, width):
        """The proposals with at least ``width`` dimensions (the chains grow with them)."""
        if width > self.v.shape[1]:
            new = self.chains.proposal_columns(width, self.rows, self.large, self.rng)
            self.v = np.concatenate([self.v, new], axis=1)
        return self.v


def metropolis_step(chains, evaluate, rng, large_step_probability, rows=None):
    """One mutation of the chains ``rows`` (None: all): propose, evaluate, splat, accept.

    Parameters
    ----------
    chains : Chains
    evaluate : callable((m, width) float64, grow) -> (L (m, 3), key (m,))
        The contribution of primary vectors and where it goes; ``grow(w)`` returns the
        vectors with ``w`` dimensions at least, for a path that reads past ``width``.
    rng : numpy.random.Generator
    large_step_probability : float
    rows : (m,) int or None

    Returns
    -------
    keys : (2 m,) int64
        Where the splats go: the proposals', then the current states'.
    values : (2 m, 3) float64
        Veach's expected values ``a L' / f'`` and ``(1 - a) L / f``; multiplied by ``b`` over
        the number of mutations they estimate the measurement of each key.
    """
    u = chains.u if rows is None else chains.u[rows]
    f, L, key = ((chains.f, chains.L, chains.key) if rows is None
                 else (chains.f[rows], chains.L[rows], chains.key[rows]))
    v, large = propose(u, rng, large_step_probability)
    proposal = Proposal(chains, rows, v, large, rng)
    L_new, key_new = evaluate(v, proposal.grow)
    v = proposal.v
    f_new = luminance(L_new)
    a = acceptance(f, f_new)
    with np.errstate(divide="ignore", invalid="ignore"):
        w_new = np.where(f_new > 0, a / np.where(f_new > 0, f_new, 1.0), 0.0)
        w_cur = np.where(f > 0, (1.0 - a) / np.where(f > 0, f, 1.0), 0.0)
    values = np.concatenate([L_new * w_new[:, None], L * w_cur[:, None]])
    keys = np.concatenate([np.asarray(key_new, np.int64), key])
    take = rng.random(a.size) < a
    idx = np.nonzero(take)[0]
    target = idx if rows is None else np.asarray(rows)[idx]
    chains.u[target] = v[idx]
    chains.L[target] = L_new[idx]
    chains.f[target] = f_new[idx]
    chains.key[target] = np.asarray(key_new, np.int64)[idx]
    chains.accepted += idx.size
    chains.proposed += a.size
    return keys, values


class PrimarySampleStream(SampleStream):
    """A :class:`SampleStream` that returns given primary vectors, dimension by dimension.

    Parameters
    ----------
    u : (n, width) float64
        One primary vector per path; ``sample(d, c)`` returns columns ``d .. d + c - 1`` of the
        rows still alive (terminated paths leave by :meth:`compact`), but dimensions 0-1,
        which come from ``inside``.
    inside : (n, 2) float64
        The numbers of dimensions 0-1 (the film position inside the pixel).
    pixel : (n,) int64
        Frame pixel of each path (read by the camera stage).
    grow : callable(int) -> (n, w) float64, or None
        The vectors with at least that many dimensions, called when a path reads past
        ``width``; None: reading past it is an error.
    limit : int
        Dimensions the integrator may read at most.
    """

    def __init__(self, u, inside, pixel, grow=None, limit=None, seed=0):
        super().__init__(pixel, np.zeros(len(pixel), np.int64), seed)
        self.u, self.inside, self.grow = u, inside, grow
        self.limit = u.shape[1] if limit is None else int(limit)
        self.rows = np.arange(len(pixel))

    def _compact_state(self, keep):
        self.rows = self.rows[keep]

    def sample(self, dimension, count):
        end = dimension + count
        if end > self.u.shape[1]:
            if self.grow is None or end > self.limit:
                raise ValueError(f"primary sample space has {self.limit} dimensions; the "
                                 f"integrator asked for dimension {end - 1}")
            # A few dimensions beyond the one asked for: fewer, smaller growths.
            self.u = self.grow(min(self.limit, max(end, self.u.shape[1] + GROW_STEP)))
        out = self.u[self.rows, dimension:end]
        if dimension < 2:
            lo, hi = dimension, min(end, 2)
            out[:, :hi - lo] = self.inside[self.rows, lo:hi]
        return out
