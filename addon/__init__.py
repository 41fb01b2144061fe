"""Everything that imports ``bpy``: the render engine, its properties, panels and exporter.

Registered by the extension entry point (the repository's ``__init__.py``). The renderer itself
lives in ``core/`` and never imports ``bpy``; this package only adapts Blender to it. The command
line is ``cli.py`` at the top of the package and runs built-in scenes without ``bpy``; it
imports :mod:`.blendfile` (and through it ``bpy`` and :mod:`.export`) only to read a ``.blend``
file. The modules that import ``bpy`` are imported here only when Blender registers the add-on.
"""


def _modules():
    from . import engine, operators, presets, properties, ui

    # Registration order: properties before the panels that draw them; reverse to unregister.
    return (properties, engine, operators, presets, ui)


def register():
    for module in _modules():
        module.register()


def unregister():
    for module in reversed(_modules()):
        module.unregister()
    # The final renders' worker processes (core.workers) end with the add-on.
    from ..core import workers

    workers.shutdown()
