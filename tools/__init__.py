"""Tools apart from the library: benchmarks, report writers and the release builder.

The library (``core``, ``addon``) never imports them, and the extension archive leaves this
folder out. Every command writes into ``out/<command>/`` or its ``--output`` folder, and into the
repository's ``docs/`` only with ``--update-docs`` (:mod:`.outputs`).

- :mod:`.commands`: their subcommands of the command line (``cli.py``).
- :mod:`.cornell`: raw embreex throughput, our path tracer and Cycles side by side on the Cornell
  box, and their error at equal time (``python -m sampling_lab bench``).
- :mod:`.strategies`: equal-time error of every sampler and MIS setting
  (``python -m sampling_lab bench-strategies``).
- :mod:`.hard_scenes`: every integrator and Cycles at equal time on hard scenes
  (``python -m sampling_lab bench-scenes``).
- :mod:`.caustic`: path, light and BDPT at equal time on the small-light glass caustic
  (``python -m sampling_lab bench-caustic``).
- :mod:`.bdpt_views`: BDPT's per-strategy images in one figure (``python -m sampling_lab
  bdpt-views``).
- :mod:`.sampler_lab`: the sampler lab's CSV files, plots and table (``python -m sampling_lab
  samplers``) over the measures of :mod:`core.sampling.lab`.
- :mod:`.viewport_cancel`: how fast the rendered viewport answers a change
  (``python -m sampling_lab.tools.viewport_cancel``).
- :mod:`.fuzz`: randomly broken scenes and command lines, each of which must render or be
  refused in one line (``python -m sampling_lab fuzz``; :mod:`.fuzz_cases`,
  :mod:`.fuzz_child`, :mod:`.fuzz_edits`).
- :mod:`.blender_scene`: a :class:`core.scene.Scene` rebuilt as a ``bpy`` scene for Cycles.
- :mod:`.bpy_scenes`: scenes built with Blender's data API, shared with the Cycles agreement
  tests.
- ``dist.py``: the release builder (``./lab dist``), run as a script.

See ``docs/BENCHMARKS.md``, ``docs/STRATEGIES.md``, ``docs/HARD_SCENES.md``.
"""
