"""The blue-noise table cache: generated point sets and masks, memoized in-process and stored
as ``.npz`` files under the user cache directory (see :mod:`.bluenoise`, "Point-set cache")."""

from __future__ import annotations

import os
import tempfile
import threading

import numpy as np

_memo = {}
# Re-entrant: a generator may itself need another cached table (a point set uses the mask).
_lock = threading.RLock()


def cache_dir():
    """The folder blue-noise tables are stored in (see the module docstring)."""
    root = os.environ.get("SAMPLING_LAB_CACHE")
    if not root:
        xdg = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        root = os.path.join(xdg, "sampling_lab")
    return os.path.join(root, "bluenoise")


def _cache_path(kind, n, seed, version):
    return os.path.join(cache_dir(), f"{kind}_n{int(n)}_s{int(seed)}_v{int(version)}.npz")


def _load(path, shape):
    try:
        with np.load(path, allow_pickle=False) as z:
            data = np.array(z["data"], np.float64)
            info = {k: float(z[k]) for k in z.files if k != "data"}
    except (OSError, ValueError, KeyError, EOFError):
        return None
    if data.shape != shape or not np.all(np.isfinite(data)) or data.min() < 0 or data.max() >= 1:
        return None
    return data, info


def _store(path, data, info):
    try:
        os.makedirs(os.path.dirname(path), exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=os.path.dirname(path), suffix=".npz.tmp")
        try:
            with os.fdopen(fd, "wb") as f:
                np.savez(f, data=data, **{k: np.float64(v) for k, v in info.items()})
            os.replace(tmp, path)
        except BaseException:
            if os.path.exists(tmp):
                os.unlink(tmp)
            raise
    except OSError:
        pass  # a read-only cache costs a regeneration next session, nothing else


def cached_table(kind, n, seed, version, shape, generate, use_disk=True):
    """A generated table, from memory, the disk cache, or ``generate()`` (then cached).

    Parameters
    ----------
    kind : str
        Generator name (part of the key and the file name).
    n, seed, version : int
        The rest of the key; bump ``version`` when the generator changes.
    shape : tuple
        Expected array shape (a file of another shape is regenerated).
    generate : callable() -> (array, dict of float)
        The generator and its figures (radius, iterations, seconds, ...).
    use_disk : bool

    Returns
    -------
    data : float64 array of ``shape``, read-only
    info : dict of float
    """
    key = (kind, int(n), int(seed), int(version))
    with _lock:
        hit = _memo.get(key)
        if hit is not None:
            return hit
        path = _cache_path(kind, n, seed, version)
        loaded = _load(path, tuple(shape)) if use_disk else None
        if loaded is None:
            data, info = generate()
            data = np.ascontiguousarray(data, np.float64)
            if data.shape != tuple(shape):
                raise ValueError(f"{kind} generator returned shape {data.shape}, not {shape}")
            if use_disk:
                _store(path, data, info)
            loaded = (data, dict(info))
        loaded[0].flags.writeable = False
        _memo[key] = loaded
        return loaded


def clear_memo():
    """Forget the in-process tables (tests use it to exercise generation and the disk cache)."""
    with _lock:
        _memo.clear()
