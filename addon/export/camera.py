"""The render camera -> :class:`core.scene.Camera`."""

from __future__ import annotations

import numpy as np

from ...core.scene import Camera
from .messages import ExportError

NO_CAMERA_MESSAGE = (
    "Sampling Lab: the scene has no camera. Add a camera object and set it as the scene "
    "camera (Scene Properties > Camera)"
)


def render_camera(depsgraph, camera_object=None):
    """The evaluated camera object to render from: ``camera_object``, else the scene camera.

    Raises
    ------
    ExportError
        There is no camera, or it is not a camera object.
    """
    camera_object = camera_object or depsgraph.scene.camera
    if camera_object is None:
        raise ExportError(NO_CAMERA_MESSAGE)
    camera_object = camera_object.evaluated_get(depsgraph)
    if camera_object.type != 'CAMERA':
        raise ExportError(f"Sampling Lab: the scene camera '{camera_object.name}' is not a "
                          f"camera object")
    return camera_object


def export_camera(scene, camera_object, messages):
    """:class:`core.scene.Camera` of ``camera_object`` at the scene's render resolution."""
    render = scene.render
    cam = camera_object.data
    width = render.resolution_x * render.resolution_percentage // 100
    height = render.resolution_y * render.resolution_percentage // 100
    cam_type = cam.type
    if cam_type not in {'PERSP', 'ORTHO'}:
        messages.add(f"Camera '{camera_object.name}': {cam_type} cameras are not supported yet; "
                     f"rendered as perspective")
        cam_type = 'PERSP'
    if getattr(cam, "dof", None) is not None and cam.dof.use_dof:
        messages.add(f"Camera '{camera_object.name}': depth of field is not supported yet; "
                     f"rendered with a pinhole camera")
    m = np.array(camera_object.matrix_world, np.float64)
    # Object scale must not scale the view: keep only rotation and translation.
    norms = np.linalg.norm(m[:3, :3], axis=0)
    m[:3, :3] /= np.where(norms > 0, norms, 1.0)
    return Camera(
        to_world=m,
        width=int(width),
        height=int(height),
        type=cam_type,
        lens=float(cam.lens),
        sensor_width=float(cam.sensor_width),
        sensor_height=float(cam.sensor_height),
        sensor_fit=cam.sensor_fit,
        shift_x=float(cam.shift_x),
        shift_y=float(cam.shift_y),
        clip_start=float(cam.clip_start),
        clip_end=float(cam.clip_end),
        ortho_scale=float(cam.ortho_scale),
        pixel_aspect_x=float(render.pixel_aspect_x),
        pixel_aspect_y=float(render.pixel_aspect_y),
    )
