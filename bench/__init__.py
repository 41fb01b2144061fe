"""Speed-against-error benchmarks: figures printed and written as CSV, never asserted.

- :mod:`.cornell`: raw embreex throughput, our path tracer and Cycles side by side on the Cornell
  box, and their error at equal time (``python -m sampling_lab bench``).
- :mod:`.strategies`: equal-time error of every sampler and MIS setting
  (``python -m sampling_lab bench-strategies``).
- :mod:`.hard_scenes`: every integrator and Cycles at equal time on hard scenes
  (``python -m sampling_lab bench-scenes``).
- :mod:`.blender_scene`: a :class:`core.scene.Scene` rebuilt as a ``bpy`` scene for Cycles.
- :mod:`.bpy_scenes`: scenes built with Blender's data API, shared with the Cycles agreement
  tests.

See ``docs/BENCHMARKS.md``, ``docs/STRATEGIES.md``, ``docs/HARD_SCENES.md``.
"""
