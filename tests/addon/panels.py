"""The add-on's panels drawn without a window: which properties a panel shows, and whether each
row is active (not greyed out)."""

import bpy

from scenes import ENGINE_ID


class LayoutRecorder:
    """Stands in for a ``UILayout``: records ``(property, active)`` of every ``prop`` call (the
    property must exist) and accepts every other layout call."""

    def __init__(self, calls, active=True):
        object.__setattr__(self, "_calls", calls)
        object.__setattr__(self, "active", active)

    def prop(self, data, name, **_):
        assert name in data.bl_rna.properties, name
        self._calls.append((name, self.active))

    def __getattr__(self, name):
        return lambda *args, **kwargs: LayoutRecorder(self._calls, self.active)

    def __setattr__(self, name, value):
        object.__setattr__(self, name, value)


def drawn_rows(panel_name, scene, header=False):
    """``{property: active}`` of the rows panel ``panel_name`` draws for ``scene`` (the panel
    must poll true for the Sampling Lab engine); ``header``: of its ``draw_header``."""

    class Context:
        engine = ENGINE_ID

    Context.scene = scene
    panel = getattr(bpy.types, panel_name)
    assert panel.poll(Context)
    calls = []
    getattr(panel, "draw_header" if header else "draw")(
        type("Panel", (), {"layout": LayoutRecorder(calls)})(), Context)
    return dict(calls)
