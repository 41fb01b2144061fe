"""The C allocator's settings for a rendering process: freed batch arrays are kept for the next
batch (:func:`core.render.render` and a worker process make them once).

A work unit makes and frees thousands of NumPy arrays of a few hundred kilobytes (a column of
16,384 rows of three float64 is 393 KB). glibc's ``malloc`` serves blocks above its mmap
threshold (128 KB at start, raised only by frees) with fresh ``mmap`` pages, and returns the
top of its heap to the system once more than its trim threshold is free there: either way the
next batch's arrays fault their pages in again, a kernel call per 4 KB page, billed to the
thread that touches them. With a fixed mmap threshold of 32 MB (glibc's largest) and a trim
threshold of 256 MB, freed batch arrays stay in the heap and are reused. Units run on a
process's main thread (the profiling tools' ``--units``, a worker process's loop) take their
memory from glibc's main arena, where this matters: on the bench box, 0.23 (path) and 0.32
(BDPT) page faults per camera sample without it, none with it, and the path tracer's CPU per
sample 2.0 -> 1.7 us. Units on worker threads (the thread pool of :mod:`core.passes`) take
theirs from per-thread arenas, which fault far less (0.05 and 0.12 per sample) and not less
with this setting (``docs/BENCHMARKS.md``, seventh round); an earlier round counted 600 k
page faults on the bench box before the setting, when units ran in larger fresh arrays. The
values computed are unchanged either way.

The cost is memory: up to the trim threshold of freed memory per ``malloc`` arena stays with
the process until it exits, instead of going back to the system between batches. Only glibc
is tuned (Linux); elsewhere :func:`keep_freed_batches` does nothing, and a process whose
``malloc`` is another allocator (a build linked with jemalloc, say) is not affected.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import sys
import threading

# mallopt's parameter numbers (glibc's malloc.h).
M_TRIM_THRESHOLD = -1
M_MMAP_THRESHOLD = -3

MMAP_THRESHOLD = 32 << 20  # glibc refuses more (half its 64 MB heap size on 64-bit)
TRIM_THRESHOLD = 256 << 20

_lock = threading.Lock()
_state = {}


def keep_freed_batches():
    """Set glibc's mmap and trim thresholds (:data:`MMAP_THRESHOLD`, :data:`TRIM_THRESHOLD`)
    once per process (call it before the first unit); later calls return the first call's
    answer. Returns a short text for stats: what was set, or why nothing was."""
    with _lock:
        if "text" not in _state:
            _state["text"] = _tune()
        return _state["text"]


def keeps_freed():
    """Whether :func:`keep_freed_batches` has tuned this process's ``malloc`` (so that freed
    batch arrays are reused without faulting their pages in again)."""
    return _state.get("text", "").startswith("glibc")


def _tune():
    if not sys.platform.startswith("linux"):
        return f"default ({sys.platform})"
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return "default (no glibc mallopt)"
    mallopt.argtypes, mallopt.restype = (ctypes.c_int, ctypes.c_int), ctypes.c_int
    if not (mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD) and
            mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD)):
        return "default (mallopt refused)"
    return f"glibc mmap threshold {MMAP_THRESHOLD >> 20} MB, trim {TRIM_THRESHOLD >> 20} MB"
