"""Building an Embree scene's BVH so that cancel can stop it, with Python's GIL released.

embreex fills a triangle mesh's buffers in a loop that holds the GIL (5.8 s for 10 M
triangles on a quiet machine) and builds the BVH (``rtcCommitScene``, 6.1 s) when the scene
is first queried, also holding the GIL and with no progress callback: nothing in Python runs
meanwhile, so neither Esc nor Ctrl-C can be answered and Blender's interface stalls.

This module does both steps through :mod:`ctypes` on the Embree library embreex has already
loaded (the same library instance, so the handles are shared), on the ``EmbreeScene`` embreex
created, whose queries then run unchanged:

1. the mesh's vertex and index buffers are filled by NumPy, :data:`FILL_ROWS` rows at a time
   with a cancel poll between steps;
2. ``rtcCommitScene`` runs on a helper thread (ctypes releases the GIL for the call) with a
   progress monitor (``rtcSetSceneProgressMonitorFunction``) that tells Embree to stop once
   cancel was asked; the calling thread polls ``cancel()`` every :data:`POLL_S` s meanwhile.
   Embree calls the monitor from its worker threads (ctypes takes the GIL for each call, which
   is free: the calling thread waits on a lock, which releases it). A stopped build ends with
   ``RTC_ERROR_CANCELLED`` and leaves the scene empty; :class:`Aborted` is raised and the scene
   dropped. Embree does not call the monitor during the first splits of a large BVH (up to
   2 s at 10 M triangles under load), so a build that has not stopped :data:`ABANDON_S` s
   after the cancel is left to stop by itself on its thread (:func:`wait_abandoned`);
3. embreex's ``is_committed`` is set, so that embreex does not build again.

The handle of the scene (``EmbreeScene.scene_i``, a C field with no Python accessor) is read
at the place embreex's declaration gives it (``scene_i, is_committed, device`` after the object
header), and only after checking that place: the ``is_committed`` field must read back a value
written through Python, the ``device`` field must point at the device object passed in, and
Embree must report that device (``rtcGetSceneDevice``) for the handle. If the library is not
found or any check fails, :func:`build_scene` falls back to embreex's own path (not
cancellable, GIL held) and its report says why.
"""

from __future__ import annotations

import ctypes
import glob
import logging
import os
import sys
import threading
import time
from dataclasses import dataclass

import numpy as np

from .sampling.stream import Aborted

log = logging.getLogger(__name__)

POLL_S = 0.02
"""Seconds between polls of ``cancel()`` while the BVH builds."""

FILL_ROWS = 1 << 20
"""Vertices or triangles copied into Embree's buffers per step (cancel is polled between)."""

RTC_ERROR_NONE, RTC_ERROR_OUT_OF_MEMORY, RTC_ERROR_CANCELLED = 0, 4, 6
RTC_GEOMETRY_TYPE_TRIANGLE = 0
RTC_BUFFER_TYPE_INDEX, RTC_BUFFER_TYPE_VERTEX = 0, 1
RTC_FORMAT_UINT3, RTC_FORMAT_FLOAT3 = 0x5003, 0x9003
_MAGIC = 0x51A7C0DE

MONITOR = ctypes.CFUNCTYPE(ctypes.c_bool, ctypes.c_void_p, ctypes.c_double)
ERROR_FUNCTION = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_int, ctypes.c_char_p)


class LayoutMismatch(Exception):
    """embreex's objects are not laid out as this module expects (another embreex version)."""


@dataclass
class BuildReport:
    """How an Embree scene was built.

    Attributes
    ----------
    method : str
        ``'ctypes'`` (cancellable, GIL released) or ``'embreex'`` (the fallback).
    reason : str
        Why the fallback was taken ('' for ``'ctypes'``).
    seconds : float
        Filling the buffers and building the BVH.
    monitor_calls : int
        Calls of the progress monitor during the build.
    refused_at_call : int
        The monitor call that first told Embree to stop (0: none did).
    error : int
        Embree's error code after the commit (``RTC_ERROR_*``).
    """

    method: str
    reason: str = ""
    seconds: float = 0.0
    monitor_calls: int = 0
    refused_at_call: int = 0
    error: int = RTC_ERROR_NONE


def _library_candidates():
    """Paths where wheels put the Embree library next to embreex (Linux: ``embreex.libs``,
    macOS: ``embreex/.dylibs``, Windows: ``embreex.libs`` or the package folder)."""
    import embreex

    package = os.path.dirname(os.path.abspath(embreex.__file__))
    folders = [package + ".libs", os.path.join(package, ".dylibs"), package]
    names = ["*embree4*.so*", "*embree4*.dylib", "*embree4*.dll"]
    return [p for f in folders for n in names for p in sorted(glob.glob(os.path.join(f, n)))]


def _load(path):
    """The library at ``path`` only if the process has loaded it already (embreex's copy)."""
    if sys.platform == "win32":
        handle = ctypes.windll.kernel32.GetModuleHandleW(path)
        if not handle:
            raise OSError(f"{path} is not loaded")
        return ctypes.CDLL(path, handle=handle)
    return ctypes.CDLL(path, mode=os.RTLD_NOLOAD | os.RTLD_LAZY | os.RTLD_GLOBAL)


def _declare(lib):
    """Set the argument and result types of the functions used here."""
    p, u, i = ctypes.c_void_p, ctypes.c_uint, ctypes.c_int
    signatures = {
        "rtcGetSceneDevice": (p, [p]), "rtcReleaseDevice": (None, [p]),
        "rtcGetDeviceError": (i, [p]), "rtcSetDeviceErrorFunction": (None, [p, p, p]),
        "rtcNewGeometry": (p, [p, i]), "rtcCommitGeometry": (None, [p]),
        "rtcSetNewGeometryBuffer": (p, [p, i, u, i, ctypes.c_size_t, ctypes.c_size_t]),
        "rtcAttachGeometry": (u, [p, p]), "rtcReleaseGeometry": (None, [p]),
        "rtcCommitScene": (None, [p]), "rtcSetSceneProgressMonitorFunction": (None, [p, p, p]),
    }
    for name, (restype, argtypes) in signatures.items():
        function = getattr(lib, name)
        function.restype, function.argtypes = restype, argtypes
    return lib


_LIBRARY = {}


def library():
    """The ctypes handle of embreex's Embree library, or a string saying why there is none."""
    if "lib" not in _LIBRARY:
        _LIBRARY["lib"] = "no Embree library found next to embreex"
        for path in _library_candidates():
            try:
                _LIBRARY["lib"] = _declare(_load(path))
                break
            except (OSError, AttributeError) as exc:
                _LIBRARY["lib"] = f"cannot use {os.path.basename(path)}: {exc}"
    return _LIBRARY["lib"]


def _pointer_at(obj, offset):
    return ctypes.c_void_p.from_address(id(obj) + offset).value


def scene_handle(lib, scene, device):
    """The ``RTCScene`` of embreex's ``scene``, created with the ``EmbreeDevice`` ``device``,
    and the device's ``RTCDevice``; raises :class:`LayoutMismatch` unless every check of the
    module docstring holds."""
    head = object.__basicsize__
    if type(scene).__basicsize__ < head + 24 or type(device).__basicsize__ < head + 8:
        raise LayoutMismatch("embreex's EmbreeScene or EmbreeDevice has another size")
    scene.is_committed = _MAGIC
    try:
        flag = ctypes.c_int.from_address(id(scene) + head + 8).value
    finally:
        scene.is_committed = 0
    if flag != _MAGIC or _pointer_at(scene, head + 16) != id(device):
        raise LayoutMismatch("embreex's EmbreeScene fields are not where expected")
    handle, device_handle = _pointer_at(scene, head), _pointer_at(device, head)
    if not handle or not device_handle:
        raise LayoutMismatch("embreex's scene or device handle is null")
    owner = lib.rtcGetSceneDevice(handle)
    lib.rtcReleaseDevice(owner)
    if owner != device_handle:
        raise LayoutMismatch("Embree does not report the scene's device")
    return handle, device_handle


def _log_error(_user, code, message):
    """Embree's error callback for the devices built here (embreex's own one calls Python
    without the GIL, which a commit through ctypes does not hold)."""
    text = message.decode(errors="replace") if message else ""
    (log.debug if code == RTC_ERROR_CANCELLED else log.error)("Embree error %d: %s", code, text)


_ERROR_CALLBACK = ERROR_FUNCTION(_log_error)


def _buffer(lib, geometry, kind, fmt, stride, count, dtype, width):
    address = lib.rtcSetNewGeometryBuffer(geometry, kind, 0, fmt, stride, count)
    if not address:
        raise MemoryError(f"Embree could not allocate a buffer of {count:,} rows")
    raw = (ctypes.c_char * (stride * count)).from_address(address)
    return np.frombuffer(raw, dtype).reshape(count, width)


def _fill(target, source, poll):
    for start in range(0, len(source), FILL_ROWS):
        rows = slice(start, start + FILL_ROWS)
        target[rows, :3] = source[rows]
        poll()


def add_triangles(lib, device, handle, vertices, triangles, poll):
    """Attach a triangle mesh of ``vertices (v, 3) float32`` and ``triangles (t, 3) int32``
    to the scene ``handle`` as embreex's ``TriangleMesh`` does (float3 vertices of stride 16,
    uint3 indices), filling the buffers in steps with ``poll()`` after each."""
    geometry = lib.rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE)
    if not geometry:
        raise MemoryError("Embree could not create a triangle mesh")
    try:
        v = _buffer(lib, geometry, RTC_BUFFER_TYPE_VERTEX, RTC_FORMAT_FLOAT3, 16,
                    len(vertices), np.float32, 4)
        v[:, 3] = 0.0
        _fill(v, vertices, poll)
        t = _buffer(lib, geometry, RTC_BUFFER_TYPE_INDEX, RTC_FORMAT_UINT3, 12,
                    len(triangles), np.int32, 3)
        _fill(t, triangles, poll)
        lib.rtcCommitGeometry(geometry)
        lib.rtcAttachGeometry(handle, geometry)
    finally:
        lib.rtcReleaseGeometry(geometry)


ABANDON_S = 0.25
"""Seconds a cancelled build is waited for before :func:`commit` returns without it."""

_ABANDONED = set()


def commit(lib, handle, device, cancel=None, report=None, keep=None):
    """Build the BVH of scene ``handle`` on a helper thread, the GIL released, polling
    ``cancel()`` every :data:`POLL_S` s; raises :class:`Aborted` if the build was stopped.
    Fills ``report``'s monitor fields (a new :class:`BuildReport` when None) and returns it.

    Embree calls the monitor often, but not during the first splits of a large BVH (up to
    2 s for 10 M triangles on a loaded machine): a build still running :data:`ABANDON_S` s
    after the cancel is left to stop by itself at the monitor's next call, on its thread,
    which holds ``keep`` (the embreex scene owning ``handle``) until then
    (:func:`wait_abandoned`)."""
    report = report or BuildReport("ctypes")
    stop, done = threading.Event(), threading.Event()

    def monitor(_user, _fraction):
        report.monitor_calls += 1
        if stop.is_set():
            report.refused_at_call = report.refused_at_call or report.monitor_calls
            return False
        return True

    callback = MONITOR(monitor)
    lib.rtcSetSceneProgressMonitorFunction(handle, callback, None)

    def work(_alive=(callback, keep)):
        try:
            lib.rtcCommitScene(handle)
            report.error = lib.rtcGetDeviceError(device)  # the committing thread's error
        finally:
            lib.rtcSetSceneProgressMonitorFunction(handle, None, None)
            done.set()

    thread = threading.Thread(target=work, name="embree-bvh-build", daemon=True)
    thread.start()
    try:
        while not done.wait(POLL_S):
            if cancel is not None and cancel():
                stop.set()
                break
    except BaseException:
        stop.set()  # a cancel hook that failed stops the build too
        _abandon(thread)
        raise
    if not done.wait(ABANDON_S if stop.is_set() else None):
        _abandon(thread)
        raise Aborted("cancelled while building Embree's BVH (it stops in the background)")
    _raise_for(report.error)
    return report


def _abandon(thread):
    _ABANDONED.difference_update([t for t in _ABANDONED if not t.is_alive()])
    _ABANDONED.add(thread)


def wait_abandoned(timeout=None):
    """Wait for the builds :func:`commit` returned without (``timeout`` s in all, None:
    until they end); whether none still runs. The command line exits at once instead
    (``os._exit``), since a process must not finalise Python while Embree's threads may
    still call into it."""
    end = None if timeout is None else time.perf_counter() + timeout
    for thread in list(_ABANDONED):
        thread.join(None if end is None else max(0.0, end - time.perf_counter()))
    _ABANDONED.difference_update([t for t in _ABANDONED if not t.is_alive()])
    return not _ABANDONED


def _raise_for(error):
    if error == RTC_ERROR_CANCELLED:
        raise Aborted("cancelled while building Embree's BVH")
    if error == RTC_ERROR_OUT_OF_MEMORY:
        raise MemoryError("Embree ran out of memory building the BVH")
    if error != RTC_ERROR_NONE:
        raise RuntimeError(f"Embree failed to build the BVH (error {error})")


def build_scene(vertices, triangles, cancel=None):
    """An embreex ``EmbreeScene`` of ``triangles (t, 3) int32`` over ``vertices (v, 3)
    float32``, its BVH built, and a :class:`BuildReport`.

    ``cancel`` (callable or None) is polled while the buffers fill and the BVH builds;
    :class:`Aborted` is raised once it says so. Through ctypes when :func:`library` and
    :func:`scene_handle` allow, otherwise by embreex (not cancellable, the report says why).
    """
    from embreex import rtcore, rtcore_scene

    t0 = time.perf_counter()
    device = rtcore.EmbreeDevice()
    scene = rtcore_scene.EmbreeScene(device)
    lib = library()
    reason = lib if isinstance(lib, str) else ""
    if not reason:
        try:
            handle, device_handle = scene_handle(lib, scene, device)
        except LayoutMismatch as exc:
            reason = str(exc)
    if reason:
        return scene, _embreex_build(scene, vertices, triangles, reason, t0)
    lib.rtcSetDeviceErrorFunction(device_handle, _ERROR_CALLBACK, None)
    report = BuildReport("ctypes")

    def poll():
        if cancel is not None and cancel():
            raise Aborted("cancelled while filling Embree's buffers")

    if len(triangles):
        add_triangles(lib, device_handle, handle, vertices, triangles, poll)
        commit(lib, handle, device_handle, cancel, report, keep=(scene, device))
    scene.is_committed = 1
    report.seconds = time.perf_counter() - t0
    return scene, report


def _embreex_build(scene, vertices, triangles, reason, t0):
    """Today's path: embreex's mesh and commit (a query of no rays commits)."""
    from embreex.mesh_construction import TriangleMesh

    log.warning("Embree's BVH build cannot be cancelled: %s", reason)
    if len(triangles):
        TriangleMesh(scene, vertices, triangles)
        empty = np.zeros((0, 3), np.float32)
        scene.run(empty, empty)
    return BuildReport("embreex", reason, time.perf_counter() - t0)
