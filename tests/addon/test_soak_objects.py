"""Repeated renders in one Blender session leave no Python objects behind.

Every job of ``tools.soak.JOBS`` (each integrator, built with the data API in the emptied
scene) renders once to warm up (imports, caches that fill once), then :data:`ROUNDS` more
times while ``tracemalloc`` traces what is allocated and not freed, and ``gc`` counts the
objects it tracks. Both are read after ``gc.collect()`` and divided by the renders: a render
that leaves anything of its own behind (its result, film, scene or messages) adds at least a
few dozen objects and kilobytes each time. Measured without a leak (24 renders): 0 objects
and 1.2 kB per render (NumPy's small internal caches). The smallest leak each bound detects:
one object that ``gc`` tracks (a list, dict or instance) per render, or 16 kB per render.
Keeping each render's core output (a leak of one small film per render) adds 36 objects and
151 kB per render at this size (second test).
"""

import gc
import importlib
import tracemalloc

from scenes import ADDON_MODULE
from sampling_lab.tools import soak

ROUNDS = 3
SIZE = (32, 24)
MAX_OBJECTS_PER_RENDER = 1.0
MAX_KB_PER_RENDER = 16.0


def _per_render_growth():
    """(objects, kB) left behind per render after a warm-up round."""
    quiet = dict(size=SIZE, spp=1, progress=lambda *_: None)
    soak.soak(rounds=1, **quiet)
    gc.collect()
    objects0 = len(gc.get_objects())
    tracemalloc.start()
    try:
        rows = soak.soak(rounds=ROUNDS, **quiet)
        gc.collect()
        traced = tracemalloc.get_traced_memory()[0]
    finally:
        tracemalloc.stop()
    renders = len(rows)
    del rows
    gc.collect()
    objects = len(gc.get_objects()) - objects0
    print(f"per render: {objects / renders:.2f} objects, {traced / renders / 1024:.2f} kB")
    return objects / renders, traced / renders / 1024


def test_repeated_renders_leave_no_python_objects(addon):
    objects, kb = _per_render_growth()
    assert objects < MAX_OBJECTS_PER_RENDER
    assert kb < MAX_KB_PER_RENDER


def test_the_object_check_sees_a_leak(addon, monkeypatch):
    core_render = importlib.import_module(f"{ADDON_MODULE}.core.render")
    kept, render = [], core_render.render

    def leaking_render(*args, **kw):
        kept.append(render(*args, **kw))
        return kept[-1]

    monkeypatch.setattr(core_render, "render", leaking_render)
    objects, kb = _per_render_growth()
    assert objects > MAX_OBJECTS_PER_RENDER and kb > MAX_KB_PER_RENDER
