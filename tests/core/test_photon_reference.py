"""The complete references of bench-photons (tools/photons_reference.py): photons flagged as
paths BDPT cannot join are exactly those, and BDPT plus SPPM's render of them is a complete
reference (a closed form agrees), while BDPT alone is caught as lacking light."""

from __future__ import annotations

import numpy as np
import pytest

from sampling_lab.core import scenes
from sampling_lab.core.integrators.base import Counters
from sampling_lab.core.photons.tracing import trace_photons
from sampling_lab.core.prepare import prepare
from sampling_lab.core.sampling.samplers import make_sampler
from sampling_lab.tools import photons_reference as pr


def _photons(scene, n, bounces, seed=4):
    prep = prepare(scene)
    stream = make_sampler("independent", seed=seed).stream(np.arange(n), np.zeros(n, np.int64))
    return trace_photons(prep, stream, bounces, Counters())


def test_unconnectable_photons_are_the_light_paths_with_no_two_rough_neighbours():
    """Between a diffuse floor and a mirror (two planes, neither can reach itself) a photon's
    hits alternate: hit 1 on the floor straight from the point light (``L D``, joined by
    next-event estimation), hit 2 after the mirror (``L S D``), hit 3 after floor and mirror
    (``L D S D``: the edge ``L D`` joins it), hit 4 ``L S D S D``. So the flag must be exactly
    "hit number even"; in the diffuse Cornell box (every vertex rough) no photon has it."""
    mirror = _photons(scenes.mirror_point_light(8, 8), 20_000, 4)
    assert set(np.unique(mirror.hit)) >= {1, 2, 3, 4}
    np.testing.assert_array_equal(mirror.unconnectable, mirror.hit % 2 == 0)
    assert (mirror.caustic <= mirror.unconnectable).all()
    box = _photons(scenes.cornell_box(8, 8), 5_000, 4)
    assert len(box) > 5_000 and not box.unconnectable.any()


def test_bdpt_plus_sppm_of_the_missing_paths_is_complete_and_bdpt_alone_is_caught():
    """The floor seen in the mirror (``point_mirror_seen``, 2 bounces): the light it reflects
    from the light's mirror image reaches the pinhole only as ``L S D S E``, which BDPT cannot
    sample (27 % of the image). The complete reference (BDPT + ReferenceSPPM's missing part)
    must agree with the closed form over the image, within 4 standard errors of its sum plus
    2 % (SPPM's blur); BDPT alone must fail the same check, both against the closed form and
    against the full SPPM image (as the benchmark checks its references). The smallest error
    of a reference this detects: 2.8 % of the image's sum (printed). Seen directly
    (``point_mirror``), the same light ``L S D E`` is BDPT's (light tracing): the missing part
    must then be empty."""
    scene = scenes.mirror_point_light(32, 32, view="mirror")
    direct, reflected, _ = scenes.mirror_point_light_reference(scene)
    closed = np.repeat((direct + reflected)[..., None], 3, axis=2)
    bdpt, var_bdpt, _ = pr.bdpt_reference(scene, 2, 0, spp=16)
    sppm = pr.sppm_reference(scene, 2, 1e9, seed=5, passes=12, photons=100_000)
    complete = bdpt + sppm["missing"]
    image = {"image": np.ones(direct.shape, bool)}
    se_complete = {"image": pr.group_se(image["image"], var_bdpt, sppm["missing_passes"])}
    se_bdpt = {"image": pr.group_se(image["image"], var_bdpt)}
    se_sppm = {"image": pr.group_se(image["image"], passes=sppm["image_passes"])}
    detect = (4 * se_complete["image"] + 0.02 * closed.sum()) / closed.sum()
    print(f"missing light {sppm['missing'].sum() / complete.sum():.1%} of the image; "
          f"detects {detect:.1%}")
    assert detect < 0.06
    good = pr.reference_check(complete, closed, image, se_complete, {})
    print(f"complete / closed form - 1: {good['image'][0]:+.2%}")
    assert good["image"][1], good
    assert not pr.reference_check(bdpt, closed, image, se_bdpt, {})["image"][1]
    assert pr.reference_check(complete, sppm["image"], image, se_complete, se_sppm)["image"][1]
    assert not pr.reference_check(bdpt, sppm["image"], image, se_bdpt, se_sppm)["image"][1]
    floor = pr.sppm_reference(scenes.mirror_point_light(16, 16), 1, 1e9, seed=5, passes=2,
                              photons=20_000)
    assert floor["image"].sum() > 0 and not floor["missing"].any()
    # With an area light the camera path can hit the light through the mirror: refused.
    with pytest.raises(ValueError, match="delta light"):
        pr.sppm_reference(scenes.cornell_box(8, 8), 1, 1e9, seed=5, passes=1, photons=1000)
