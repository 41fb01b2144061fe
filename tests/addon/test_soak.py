"""Repeated renders in one Blender session keep their memory flat (``tools/soak.py``; the long
run is ``python -m sampling_lab bench-soak``).

Six renders of a 256 x 192 Cornell box: from the third (after imports, Embree and the
allocator's pools have warmed up) to the sixth, the resident set may grow by at most
:data:`LEAK_MB`. Measured without a leak: under 1 MB over twelve renders. A leak of each
render's result (film and prepared scene, about 10 MB at this size) grows it by far more, which
the second test shows by making one.
"""

import importlib

from scenes import ADDON_MODULE
from sampling_lab.tools import soak

LEAK_MB = 15.0
JOB = (("cornell_point", "path"),)


def _growth():
    rows = soak.soak(rounds=6, size=(256, 192), spp=1, jobs=JOB, progress=lambda *_: None)
    return rows[-1]["rss_mb"] - rows[2]["rss_mb"]


def test_repeated_renders_do_not_grow_memory(addon):
    grown = _growth()
    print(f"RSS growth over 3 renders: {grown:+.1f} MB")
    assert grown < LEAK_MB


def test_the_memory_check_sees_a_leak(addon, monkeypatch):
    core_render = importlib.import_module(f"{ADDON_MODULE}.core.render")
    kept, render = [], core_render.render

    def leaking_render(*args, **kw):
        kept.append(render(*args, **kw))
        return kept[-1]

    monkeypatch.setattr(core_render, "render", leaking_render)
    grown = _growth()
    print(f"RSS growth over 3 leaking renders: {grown:+.1f} MB")
    assert grown > LEAK_MB
