"""Speed-against-error benchmarks: figures printed and written as CSV, never asserted.

- :mod:`.cornell`: raw embreex throughput, our path tracer and Cycles side by side on the Cornell
  box, and their error at equal time (``python -m sampling_lab bench``).
- :mod:`.blender_scene`: a :class:`core.scene.Scene` rebuilt as a ``bpy`` scene for Cycles.

See ``docs/BENCHMARKS.md``.
"""
