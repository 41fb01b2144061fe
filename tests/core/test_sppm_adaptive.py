"""SPPM's adaptive radius (core/photons/adaptive.py, Initial Radius: Adaptive): Lepski's rule
keeps the radius where photons are uniform and halves it where the disk reaches a bright edge;
a pixel that switches takes its smaller disk's SPPM state, so the image stays SPPM's (the
mirror image of a point light, closed form, with every pixel forced to its smallest disk); the
option changes the render and its stats say so."""

from __future__ import annotations

import numpy as np

from sampling_lab.core import render, scenes
from sampling_lab.core.photons import adaptive
from sampling_lab.core.photons.adaptive import NestedDisks, lepski_choice, scale_sums
from tests.core.test_sppm import _settings, mirror_reference

RNG_SEED = 13


def _disks(rng, n, density):
    """Photons around ``n`` points (unit radius, contribution 1) drawn from ``density(d)``
    photons per unit area at distance ``d``, by thinning a Poisson process of the largest
    density; returns :func:`lepski_choice`'s inputs with ``s = 0`` the unit disk."""
    peak = density(np.linspace(0, 1, 257)).max()
    counts = rng.poisson(peak * np.pi, n)
    i = np.repeat(np.arange(n), counts)
    d = np.sqrt(rng.random(i.size))  # uniform over the unit disk
    keep = rng.random(i.size) < density(d) / peak
    i, d = i[keep], d[keep]
    contrib = np.ones((i.size, 3))
    phi, m = scale_sums(i, d, contrib, np.ones(n), n)
    tau0 = np.stack([np.bincount(i, minlength=n).astype(float)] * 3, axis=1)
    tau = np.concatenate([tau0[:, None], phi], axis=1)
    count = np.concatenate([tau0[:, :1], m], axis=1)
    return tau, count, np.full(n, adaptive.SCALES - 1)


def test_lepski_keeps_the_radius_where_the_photons_are_uniform():
    """Uniform photons (on average 60 per disk, about 1 in its smallest disk): the rule keeps
    the radius for at least 99 % of 20,000 disks (a false halving costs noise, never
    correctness). Measured: 0.03 % halved. The 99 % bound has a binomial margin of 7 standard
    errors over a 1 % rate; a rule that compared estimates without their noise would halve
    most disks."""
    rng = np.random.default_rng(RNG_SEED)
    s = lepski_choice(*_disks(rng, 20_000, lambda d: np.full(np.shape(d), 60 / np.pi)))
    print(f"uniform: halved {np.mean(s > 0):.2%}")
    assert np.mean(s > 0) < 0.01


def test_lepski_halves_the_radius_where_the_disk_reaches_a_bright_caustic():
    """A dim centre (100 photons per unit area) ringed by light 10 times brighter beyond
    0.3 of the radius (a caustic's edge): the disks of radius 1 and 1/2 reach into it, the one
    of 1/4 does not, so the rule must pick 1/4 (s = 2) for at least 95 % of 1,000 points and
    never keep the full radius. Measured: 100 % at s = 2. A rule that ignored the nested
    disks, or picked the smallest disk regardless, fails."""
    rng = np.random.default_rng(RNG_SEED + 1)
    s = lepski_choice(*_disks(rng, 1000, lambda d: np.where(d < 0.3, 100.0, 1000.0)))
    print(f"caustic edge: choices {np.bincount(s, minlength=adaptive.SCALES) / s.size}")
    assert np.mean(s == 2) >= 0.95 and not np.any(s == 0)


def test_a_switch_takes_the_smaller_disks_state_and_stops_after_the_last_halving():
    """A pixel that picks disk s takes its flux, count and radius r / 2^s, its remaining
    nested disks move up by s, and a pixel that has halved SCALES - 1 times never switches."""
    n, k = 2, adaptive.SCALES - 1
    state = {"r": np.array([1.0, 1.0]), "N": np.array([400.0, 400.0]),
             "tau": np.full((n, 3), 400.0)}
    disks = NestedDisks(n)
    # Both: a bright outer ring; disks 1.. are dim (1 photon per unit area of the unit disk).
    disks.tau[:] = (4.0 ** -np.arange(1, k + 1) * 3.0)[None, :, None] * np.ones((n, k, 3))
    disks.count[:] = 4.0 ** -np.arange(1, k + 1) * 3.0
    disks.halvings[1] = k
    switched = disks.switch(state, np.arange(n))
    assert switched == 1
    assert state["r"][0] == 0.5 and state["N"][0] == 0.75 and (state["tau"][0] == 0.75).all()
    np.testing.assert_array_equal(disks.count[0, :k - 1], 3.0 * 4.0 ** -np.arange(2, k + 1))
    assert disks.count[0, k - 1] == 0 and disks.halvings[0] == 1
    assert state["r"][1] == 1.0 and state["N"][1] == 400.0 and disks.halvings[1] == k


def test_sppm_forced_to_its_smallest_disks_still_reproduces_the_mirror_image(monkeypatch):
    """The state a switch hands over is an SPPM state: with the threshold at zero every pixel
    that finds photons switches to its smallest disk (r / 8) at once, and the floor's
    reflected light (closed form: the light's mirror image, as in test_sppm.py) must still
    come out within 2 % (the bound test_sppm.py uses for plain SPPM; a flux or count handed
    over without its disk's area, or a radius not halved, is off by a factor of 4 or more).
    Measured: +0.84 % (968 halvings)."""
    monkeypatch.setattr(adaptive, "KAPPA", 0.0)
    scene = scenes.mirror_point_light(32, 32)
    direct, reflected, _ = mirror_reference(scene)
    res = render.render(scene, _settings(spp=12, photons=100_000, max_bounces=1, seed=1,
                                         sppm_radius="adaptive"))
    got = res.film.mean()[..., 0].sum() - direct.sum()
    print(f"forced halvings {res.stats['photon_radius_halvings']}: reflected "
          f"{got / reflected.sum() - 1:+.2%}")
    lit = int(np.count_nonzero(reflected > 0))
    assert res.stats["photon_radius_halvings"] >= 0.9 * lit * (adaptive.SCALES - 1)
    assert abs(got / reflected.sum() - 1) < 0.02


def test_the_adaptive_radius_changes_the_render_and_the_stats_say_so():
    """Initial Radius: Adaptive is active (Radius 0) and changes SPPM's image of the glass
    ball's caustic, and the stats report the halvings; with a Radius set it does not apply
    (used_settings says n/a, as for Pixel Footprint)."""
    scene = scenes.cornell_sphere(16, 16, ball="glass", light="point")

    def run(**kw):
        return render.render(scene, _settings(spp=4, photons=50_000, seed=2, max_bounces=4,
                                              **kw))

    base, other = run(sppm_radius="scene"), run()  # Adaptive is the default
    assert np.isfinite(other.combined()).all()
    assert not np.array_equal(base.combined(), other.combined())
    assert other.stats["photon_radius_halvings"] > 0
    assert base.stats["photon_radius_halvings"] == "n/a"
    fixed = render.used_settings(_settings(sppm_radius="adaptive", photon_radius=0.05))
    assert fixed["sppm_radius"] == "n/a"
