"""What the stage profiles ``tools/profile_path.py`` and ``tools/profile_bidir.py`` share:
exclusive thread-CPU timers around functions, and the bounce limits they render with (a
measurement aid, not a test).

The scripts run by path (``python tools/profile_path.py``) and import this module from their
own folder, so that they can profile another tree put first on ``PYTHONPATH``.
"""

from __future__ import annotations

import functools
import threading
import time
from collections import defaultdict

TOTALS = defaultdict(float)
_LOCAL = threading.local()
_LOCK = threading.Lock()


def timed(name, fn):
    """``fn`` with its exclusive CPU time (of the calling thread, so that other processes' load
    on a shared machine does not count) added to ``TOTALS[name]`` (nested stages
    subtracted)."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        stack = getattr(_LOCAL, "stack", None)
        if stack is None:
            stack = _LOCAL.stack = []
        stack.append(0.0)
        t0 = time.thread_time()
        try:
            return fn(*args, **kwargs)
        finally:
            dt = time.thread_time() - t0
            children = stack.pop()
            if stack:
                stack[-1] += dt
            with _LOCK:
                TOTALS[name] += dt - children

    return wrapper


def patch(owner, attr, name):
    """Replace ``owner.attr`` by :func:`timed` of it, counted as stage ``name``."""
    setattr(owner, attr, timed(name, getattr(owner, attr)))


def uniform_bounces(settings_class, total):
    """Every bounce limit the measured tree's ``RenderSettings`` has, set to ``total`` (older
    trees have ``max_bounces`` only), so that trees are profiled on the same paths."""
    names = ("max_bounces", "diffuse_bounces", "glossy_bounces", "transmission_bounces",
             "transparent_max_bounces")
    return {name: total for name in names if name in settings_class.__dataclass_fields__}
