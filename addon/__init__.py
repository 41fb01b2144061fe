"""Everything that imports ``bpy``: the render engine, its properties, panels and exporter.

Registered by the extension entry point (the repository's ``__init__.py``). The renderer itself
lives in ``core/`` and never imports ``bpy``; this package only adapts Blender to it. The command
line (:mod:`.cli`) lives here too and must run built-in scenes without ``bpy``, so the modules
that import ``bpy`` are imported only when Blender registers the add-on.
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
