"""The viewport's progressive worker (``core.progressive``) without Blender.

Checks: the stages of one render share one prepared scene (the full film's stage reuses the
preview's acceleration structure and light tables) and still give the image of a fresh render
with the same samples, bit for bit.
"""

import numpy as np

from sampling_lab.core import scenes
from sampling_lab.core.progressive import ProgressiveRender
from sampling_lab.core.render import render
from tests.helpers import plain_settings


def test_stages_share_one_prepared_scene_and_the_full_film_equals_a_fresh_render():
    scene = scenes.cornell_box(32, 24)
    settings = plain_settings(seed=5, max_bounces=3, threads=2)
    worker = ProgressiveRender()
    worker.start(scene, settings, [(4, 1), (2, 1), (1, 2)])
    assert worker.wait(timeout=60)
    assert worker.error == ""
    stats, frame = worker.stats, worker.frame()
    assert stats["stage"] == 2 and not stats["cancelled"]
    assert stats["prepared_reused"]
    assert frame.final and frame.spp == 2 and frame.pixel_size == 1
    fresh = render(scene, plain_settings(seed=5, max_bounces=3, threads=2, spp=2)).combined()
    np.testing.assert_array_equal(frame.pixels, fresh)
