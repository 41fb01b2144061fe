"""Sampling Lab: a Blender render engine for studying Monte Carlo sampling.

The repository root is two things at once:

- a Blender extension (``bl_ext.<repo>.sampling_lab``): Blender calls :func:`register` and
  :func:`unregister`, which delegate to :mod:`.addon`, the only part that imports ``bpy``;
- the pip-installable package ``sampling_lab``, whose users (the command line, benchmarks,
  ``tests/core``) import :mod:`sampling_lab.core` without Blender.

Nothing here may import ``bpy`` at import time, so :mod:`.addon` is imported lazily.
"""

__version__ = "0.1.0"

# Blender's "Reload Scripts" re-executes this module in place: forget the cached submodules so
# that register() imports their current code.
if "addon" in globals():
    import sys as _sys

    for _name in [n for n in _sys.modules if n.startswith(__name__ + ".")]:
        del _sys.modules[_name]
    for _name in ("addon", "core"):
        globals().pop(_name, None)
    del _sys, _name


def register():
    """Register the render engine, its properties and panels with Blender."""
    from . import addon

    addon.register()


def unregister():
    """Undo :func:`register`."""
    from . import addon

    addon.unregister()
