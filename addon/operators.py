"""Operators of Sampling Lab (Blender's side; the work is done in ``core``)."""

import os

import bpy
from bpy.props import BoolProperty, IntProperty, StringProperty
from bpy.types import Operator

NO_TOOLS = ("Sampler Lab needs a source checkout of Sampling Lab: its report writer is "
            "tools/sampler_lab.py, which the extension archive leaves out (there, run "
            "'python -m sampling_lab samplers --output DIR' from a checkout)")


def _report_writer():
    """``tools.sampler_lab`` of a source checkout, or None in an installed extension archive."""
    import importlib

    try:
        return importlib.import_module("..tools.sampler_lab", __package__)
    except ModuleNotFoundError as exc:
        if not (exc.name or "").endswith(("tools", "tools.sampler_lab")):
            raise
        return None


class SAMPLINGLAB_OT_sampler_lab(Operator):
    """Measure every sampler: its first points, Fourier spectrum, star discrepancy and the variance of a checkerboard integral against the sample count. Writes CSV files, PNG plots and a markdown table (SAMPLERS.md) to a folder. Needs a source checkout of Sampling Lab (its report writer is in tools/, which the extension archive leaves out)"""

    bl_idname = "samplinglab.sampler_lab"
    bl_label = "Sampler Lab"
    bl_options = {'REGISTER'}

    directory: StringProperty(
        name="Folder",
        description="Folder the CSV files, PNG plots and SAMPLERS.md are written to ('//' is "
                    "the folder of the .blend file)",
        subtype='DIR_PATH',
        options={'PATH_SUPPORTS_BLEND_RELATIVE'},
        default="//sampler_lab",
    )
    points: IntProperty(
        name="Points",
        description="Points per set N: each sampler's first N samples of one pixel are "
                    "plotted, their spectrum and star discrepancy measured",
        default=256, min=2, max=8192, soft_max=1024,
    )
    quick: BoolProperty(
        name="Quick",
        description="Fewer pixels, realizations and sample counts: seconds instead of about a "
                    "minute, with noisier figures",
        default=False,
    )

    @classmethod
    def poll(cls, context):
        if _report_writer() is None:
            cls.poll_message_set(NO_TOOLS)
            return False
        return True

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {'RUNNING_MODAL'}

    def execute(self, context):
        from ..core.sampling.samplers import available

        if self.directory.startswith("//") and not bpy.data.filepath:
            self.report({'ERROR'}, "The .blend file is not saved, so '//' has no folder: save "
                                   "it or choose an absolute folder")
            return {'CANCELLED'}
        folder = os.path.abspath(bpy.path.abspath(self.directory))
        wm = context.window_manager
        total = len(available())
        done = []

        def log(message):
            # One message per sampler measured: advance the progress indicator.
            done.append(message)
            wm.progress_update(min(len(done), total))

        wm.progress_begin(0, max(total, 1))
        try:
            result = _report_writer().run(output=folder, n=self.points, quick=self.quick,
                         markdown=os.path.join(folder, "SAMPLERS.md"), log=log)
        except (OSError, ValueError) as exc:
            self.report({'ERROR'}, f"Sampler Lab: {exc}")
            return {'CANCELLED'}
        finally:
            wm.progress_end()
        for name, message in result["failures"]:
            self.report({'WARNING'}, f"Sampler Lab: {name} failed: {message}")
        if not result["plots"]:
            self.report({'WARNING'}, "Sampler Lab: matplotlib is not installed in Blender's "
                                     "Python, so only CSV files and the table were written")
        self.report({'INFO'}, f"Sampler Lab: {len(result['results'])} samplers measured, "
                              f"{len(result['files'])} files in {folder}")
        return {'FINISHED'}


classes = (SAMPLINGLAB_OT_sampler_lab,)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
