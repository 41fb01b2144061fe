"""Work units in worker processes: the render loop's units without the GIL between them.

Python threads share one GIL: the NumPy integrators hold it for a sixth (path tracing) to a
third (BDPT) of their time, so threads scale worse than processes (issue 12). A
:class:`WorkerPool` keeps child Python processes (``sys.executable``: inside Blender its bundled
Python, which cannot import ``bpy``; the children import only ``core``, :mod:`.worker_child`)
and talks to them over pipes with pickle.

- The pool is started lazily, one per process (:func:`pool`), and kept across renders: the
  bench's repeated renders and a Blender session pay the start-up once. A child exits when its
  stdin closes (the parent quit or crashed: no orphans); :func:`shutdown` (the add-on's
  ``unregister()``, interpreter exit) closes them.
- A render (:class:`ProcessUnits`) ships its scene to a child only when the child has not
  prepared that scene yet (same :func:`core.render.preparation_key`); the child runs
  :func:`core.prepare.prepare` itself and keeps the result, as persistent data does.
- :meth:`ProcessUnits.submit` sends one work unit and returns a ``Future`` of
  :func:`core.passes.render_unit`'s result: the render loop accumulates the units in plan
  order, so the image is the thread render's bit for bit.
- Cancel: :meth:`ProcessUnits.stop` sends a stop message that a reader thread in the child
  reads while a unit runs; the unit stops at its next bounce.
- A unit that raises fails its future with :class:`WorkerUnitError` (the child's message and
  traceback); a child that dies fails its units with :class:`WorkerDied` (naming its exit code),
  and the pool starts a new one at the next render.
"""

from __future__ import annotations

import atexit
import itertools
import json
import os
import pickle
import subprocess
import sys
import threading
import time
from concurrent.futures import Future

# Seconds a dying child may take to exit before it is killed; a stopping pool waits as long.
EXIT_WAIT_S = 5.0

# Run by ``sys.executable -c``: import the parent's package under the parent's name (pickles
# name classes by module: ``sampling_lab.core...`` on the command line,
# ``bl_ext.<repo>.sampling_lab.core...`` in Blender), with empty parent packages where it has
# parents, and serve work units. The package's ``__init__`` imports nothing of ``bpy``.
BOOT = """
import importlib, importlib.util, json, os, sys, types
header = json.loads(sys.argv[1])
sys.path[:] = header["path"]
name, parts = header["package"], header["package"].split(".")
for i in range(1, len(parts)):
    parent = ".".join(parts[:i])
    if parent not in sys.modules:
        module = types.ModuleType(parent)
        module.__path__ = []
        sys.modules[parent] = module
spec = importlib.util.spec_from_file_location(
    name, os.path.join(header["directory"], "__init__.py"),
    submodule_search_locations=[header["directory"]])
package = importlib.util.module_from_spec(spec)
sys.modules[name] = package
spec.loader.exec_module(package)
importlib.import_module(name + ".core.worker_child").main()
"""

_ids = itertools.count()

# Memory a worker process holds per triangle of the scene (the scene, its prepared tables and
# Embree's BVH): a render of 10 M triangles peaked at 3.9 GB in one process (docs/HARD_CASES.md),
# an upper bound of what each worker copies.
WORKER_BYTES_PER_TRIANGLE = 400


def memory_note(n_triangles, count, memory=None):
    """Why ``count`` workers would not fit: ``''`` if their copies of a scene of
    ``n_triangles`` need at most half of the machine's ``memory`` (default: all of it), else
    the reason threads (one copy) are used instead."""
    from .film import physical_memory

    memory = physical_memory() if memory is None else memory
    need = count * n_triangles * WORKER_BYTES_PER_TRIANGLE
    if not memory or need <= memory / 2:
        return ""
    return (f"{count} worker processes would each copy the {n_triangles:,} triangles (about "
            f"{need / 2 ** 30:.1f} GB in all, more than half of the "
            f"{memory / 2 ** 30:.0f} GB here): threads share one copy")


class WorkerUnitError(RuntimeError):
    """A work unit raised in a worker process.

    Attributes
    ----------
    error : str
        ``"TypeName: message"`` of the child's exception.
    remote_traceback : str
        The child's traceback.
    """

    def __init__(self, error, remote_traceback):
        super().__init__(f"{error} (in a worker process)")
        self.error, self.remote_traceback = error, remote_traceback


class WorkerDied(RuntimeError):
    """A worker process exited while it had work units."""


class WorkersBusy(RuntimeError):
    """Another render of this process is using the worker processes."""


def package_name():
    """The name this package is imported under (``sampling_lab``, or
    ``bl_ext.<repo>.sampling_lab`` in Blender)."""
    return __name__.rsplit(".", 2)[0]


def package_directory():
    return os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


class _Child:
    """One worker process, its pending units and a reader thread that resolves them."""

    def __init__(self):
        header = json.dumps({"path": list(sys.path), "package": package_name(),
                             "directory": package_directory()})
        # One worker is one thread: NumPy's BLAS pool would only compete with the siblings.
        env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1",
                   MKL_NUM_THREADS="1")
        self.proc = subprocess.Popen([sys.executable, "-c", BOOT, header],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, env=env)
        self.pending = {}  # unit id -> Future
        self.lock = threading.Lock()
        self.dead = None  # WorkerDied once the child has gone
        self.key = None  # preparation key of the scene the child holds
        threading.Thread(target=self._read, daemon=True).start()

    def alive(self):
        return self.dead is None and self.proc.poll() is None

    def send(self, data):
        """Write pickled bytes; :class:`WorkerDied` if the child is gone."""
        try:
            self.proc.stdin.write(data)
            self.proc.stdin.flush()
        except (OSError, ValueError):
            raise self._exit_error() from None

    def submit(self, data, future):
        with self.lock:
            if self.dead is not None:
                raise self.dead
            uid = next(_ids)
            self.pending[uid] = future
        self.send(pickle.dumps(("unit", uid, data), pickle.HIGHEST_PROTOCOL))

    def _read(self):
        try:
            while True:
                kind, uid, *rest = pickle.load(self.proc.stdout)
                with self.lock:
                    future = self.pending.pop(uid, None)
                if future is None:
                    continue
                if kind == "error":
                    self.key = None  # it may have failed to prepare the scene
                    future.set_exception(WorkerUnitError(*rest))
                else:
                    future.set_result(rest[0])
                # Not kept alive while the next message is awaited (it may be minutes).
                del future, rest
        except Exception:  # noqa: BLE001 - end of output, or a broken message: the child is gone
            pass
        error = self._exit_error()
        with self.lock:
            self.dead, futures = error, list(self.pending.values())
            self.pending.clear()
        for future in futures:
            future.set_exception(error)

    def wait_or_kill(self, timeout=EXIT_WAIT_S):
        """The child's exit code once it has exited, killing it after ``timeout`` seconds."""
        try:
            return self.proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            return self.proc.wait()

    def _exit_error(self):
        code = self.wait_or_kill()
        why = f" (killed by signal {-code})" if code < 0 else ""
        return WorkerDied(f"a worker process (pid {self.proc.pid}) exited with code "
                          f"{code}{why}; the samples finished before are kept")

    def close(self):
        try:
            self.proc.stdin.close()
        except OSError:
            pass


class WorkerPool:
    """The worker processes of this process, started lazily and kept across renders."""

    def __init__(self):
        self.children = []
        self.lock = threading.Lock()
        self.started = 0  # processes started, over the pool's life
        self.in_use = False  # a render holds the workers (one at a time: see take())

    def take(self, count):
        """``count`` live workers (dead ones replaced) for one render, until :meth:`release`;
        returns them and the seconds spent starting new ones. :class:`WorkersBusy` while
        another render holds them (a worker runs one render's units at a time)."""
        t0 = time.perf_counter()
        with self.lock:
            if self.in_use:
                raise WorkersBusy("the worker processes are busy with another render")
            self.in_use = True
            for child in [c for c in self.children if not c.alive()]:
                child.close()
            self.children = [c for c in self.children if c.alive()]
            try:
                while len(self.children) < count:
                    self.children.append(_Child())
                    self.started += 1
            except BaseException:
                self.in_use = False
                raise
            return self.children[:count], time.perf_counter() - t0

    def release(self):
        """The render that took the workers has ended."""
        with self.lock:
            self.in_use = False

    def shutdown(self, timeout=EXIT_WAIT_S):
        """Close every worker's stdin and wait for it to exit (kill it after ``timeout``)."""
        with self.lock:
            children, self.children = self.children, []
        for child in children:
            child.close()
        for child in children:
            child.wait_or_kill(timeout)


_pool = []


def pool():
    """This process's :class:`WorkerPool` (made on first use)."""
    if not _pool:
        _pool.append(WorkerPool())
    return _pool[0]


def shutdown():
    """Stop this process's workers (the add-on's ``unregister()``; interpreter exit)."""
    if _pool:
        _pool[0].shutdown()


atexit.register(shutdown)


class ProcessUnits:
    """The work units of one render on ``count`` worker processes.

    Parameters
    ----------
    scene : core.scene.Scene
        Shipped to the workers that do not hold it yet (by ``key``).
    settings : core.render.RenderSettings
    key : str
        :func:`core.render.preparation_key` of ``scene`` and ``settings``.
    window : tuple
        The film's ``(x0, y0, width, height)`` in frame pixels.
    frame_width : int

    Attributes
    ----------
    start_s, ship_s : float
        Seconds spent starting workers (0 when the pool already had them) and sending the
        render's scene and settings.
    shipped : int
        Workers that were sent the scene (the others held it already).
    """

    def __init__(self, count, scene, settings, key, window, frame_width):
        self.children, self.start_s = pool().take(count)
        try:
            self._start(scene, settings, key, window, frame_width)
        except BaseException:
            self.release()
            raise

    def release(self):
        """Give the workers back to the pool (the render has ended; units of it still in
        flight are stopped or finish before the next render's, in each worker's order)."""
        pool().release()

    def _start(self, scene, settings, key, window, frame_width):
        t0 = time.perf_counter()
        self.render_id = next(_ids)
        head = ("render", self.render_id, key)
        tail = (scene.camera, settings, tuple(int(v) for v in window), int(frame_width))
        bare = pickle.dumps(head + (None,) + tail, pickle.HIGHEST_PROTOCOL)
        full = None
        self.shipped = 0
        for child in self.children:
            if child.key != key:
                if full is None:
                    full = pickle.dumps(head + (scene,) + tail, pickle.HIGHEST_PROTOCOL)
                child.send(full)
                child.key = key
                self.shipped += 1
            else:
                child.send(bare)
        self.ship_s = time.perf_counter() - t0

    def submit(self, unit):
        """Send ``unit`` to the worker with the fewest pending units; a ``Future`` of its
        :func:`core.passes.render_unit` result (running from the start: it cannot be
        cancelled, only stopped)."""
        child = min(self.children, key=lambda c: len(c.pending))
        future = Future()
        future.set_running_or_notify_cancel()
        child.submit(unit, future)
        return future

    def stop(self):
        """Stop this render's units at their next bounce (those queued return at once)."""
        self._tell("stop")

    def close(self):
        """The render is out of time: the units running finish, the queued ones return None
        without running."""
        self._tell("close")

    def _tell(self, what):
        data = pickle.dumps((what, self.render_id), pickle.HIGHEST_PROTOCOL)
        for child in self.children:
            try:
                child.send(data)
            except WorkerDied:
                pass
