"""Multilayer OpenEXR in Blender's layout, and 8-bit sRGB PNG previews; every write is atomic.

Blender's multilayer EXR names each channel ``<view layer>.<pass>.<channel>``, e.g.
``ViewLayer.Combined.R``. The channel letters are the pass's channel id: ``RGBA`` for Combined,
``Z`` for Depth and Mist, ``XYZ`` for Normal, ``X`` for one-channel AOVs, and so on
(:data:`BLENDER_PASS_CHANNELS`). Blender 5 writes one EXR *part* per pass, named
``<view layer>.<pass>``, with FLOAT pixels and ZIP compression; older Blenders wrote one part
holding all channels. :func:`write_multilayer` writes the Blender 5 layout (which Blender 4.2+
reads too) and :func:`read_multilayer` reads either.

Arrays here follow Blender's render-result convention: ``(h, w, c)`` float32, **row 0 is the
bottom row** of the image. EXR stores the top scanline first, so rows are flipped on the way
in and out.

Writes go to a temporary file in the target's directory, are flushed and fsync'd, then
``os.replace``-d onto the target: a reader sees the old file or the new one, never a partial
file, and a failed write leaves the old file untouched and no temporary file behind.
"""

from __future__ import annotations

import os
import struct
import tempfile
import zlib

import numpy as np

__all__ = [
    "BLENDER_PASS_CHANNELS",
    "write_multilayer",
    "read_multilayer",
    "read_metadata",
    "render_metadata",
    "write_png_preview",
    "srgb_oetf",
]

#: Channel ids of Blender's built-in passes (as verified in a Blender 5.0 render: Combined,
#: Depth, Mist, Normal, Noisy Image; the others from Blender's pass table). Passes not listed
#: get ``X`` (1 channel), ``XY`` (2), ``RGB`` (3) or ``RGBA`` (4), as Blender does for engine
#: passes and AOVs.
BLENDER_PASS_CHANNELS = {
    "Combined": "RGBA",
    "Noisy Image": "RGBA",
    "Depth": "Z",
    "Mist": "Z",
    "Normal": "XYZ",
    "Position": "XYZ",
    "Vector": "XYZW",
    "UV": "UVA",
    "IndexOB": "X",
    "IndexMA": "X",
    "Denoising Normal": "XYZ",
    "Denoising Albedo": "RGB",
    "Denoising Depth": "Z",
}

_DEFAULT_CHANNELS = {1: "X", 2: "XY", 3: "RGB", 4: "RGBA"}

# Reading order of channel letters within a pass: R,G,B,A / X,Y,Z,W / U,V,A; others after.
_CHANNEL_RANK = {c: i for i, c in enumerate("RGBXYZWUVA")}


def _openexr():
    # Import lazily so modules that only need PNG previews work without the OpenEXR wheel.
    import OpenEXR

    return OpenEXR


# --------------------------------------------------------------------------------------------
# Atomic file replacement
# --------------------------------------------------------------------------------------------


def _default_file_mode():
    """``0o666`` less the process umask, read without changing it (os.umask is not thread-safe)."""
    try:
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("Umask:"):
                    return 0o666 & ~int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    return 0o644


def _atomic_write(path, write):
    """Call ``write(fileobj)`` on a temporary file beside ``path``, then replace ``path`` with it.

    Parameters
    ----------
    path : str or os.PathLike
    write : callable, (binary file object) -> None
    """
    path = os.path.abspath(os.fspath(path))
    directory = os.path.dirname(path)
    os.makedirs(directory, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix="." + os.path.basename(path) + ".", suffix=".tmp",
                               dir=directory)
    try:
        with os.fdopen(fd, "wb") as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, _default_file_mode())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
    # Make the rename itself durable; not every platform or file system allows fsync on a dir.
    try:
        dir_fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(dir_fd)
    except OSError:
        pass
    finally:
        os.close(dir_fd)


# --------------------------------------------------------------------------------------------
# EXR
# --------------------------------------------------------------------------------------------


def _check_name(kind, name):
    if not isinstance(name, str) or not name:
        raise ValueError(f"{kind} name must be a non-empty string, got {name!r}")
    if kind == "pass" and "." in name:
        raise ValueError(f"pass name {name!r} must not contain '.' (Blender splits on it)")


def _prepare_layers(layers, channel_ids):
    """Validate passes and return [(pass name, channel letters, (h, w, c) float32 top-first)]."""
    if not isinstance(layers, dict) or not layers:
        raise ValueError("layers must be a non-empty dict of pass name -> (h, w, c) array")
    channel_ids = channel_ids or {}
    prepared = []
    size = None
    for name, array in layers.items():
        _check_name("pass", name)
        a = np.asarray(array)
        if not (np.issubdtype(a.dtype, np.floating) or np.issubdtype(a.dtype, np.integer)
                or a.dtype == np.bool_):
            raise TypeError(f"pass {name!r}: pixels must be numeric, got dtype {a.dtype}")
        if a.ndim == 2:
            a = a[:, :, None]
        if a.ndim != 3 or a.shape[0] < 1 or a.shape[1] < 1:
            raise ValueError(f"pass {name!r}: expected an (h, w, c) array, got shape {a.shape}")
        if size is None:
            size = a.shape[:2]
        elif a.shape[:2] != size:
            raise ValueError(f"pass {name!r}: size {a.shape[:2]} differs from {size}")
        chans = channel_ids.get(name) or BLENDER_PASS_CHANNELS.get(name)
        if chans is None or len(chans) != a.shape[2]:
            if name in channel_ids:
                raise ValueError(f"pass {name!r}: channel ids {chans!r} for {a.shape[2]} channels")
            chans = _DEFAULT_CHANNELS.get(a.shape[2])
            if chans is None:
                raise ValueError(f"pass {name!r}: {a.shape[2]} channels need explicit channel_ids")
        if len(set(chans)) != len(chans):
            raise ValueError(f"pass {name!r}: repeated channel ids {chans!r}")
        # EXR stores the top row first; our row 0 is the bottom.
        prepared.append((name, chans, np.ascontiguousarray(a[::-1], dtype=np.float32)))
    # Blender writes Combined first; keep the caller's order otherwise.
    prepared.sort(key=lambda item: item[0] != "Combined")
    return prepared


def write_multilayer(path, layers, layer_name="ViewLayer", channel_ids=None, metadata=None):
    """Write render passes as a Blender-style multilayer OpenEXR file, atomically.

    One EXR part per pass, named ``<layer_name>.<pass>``, holding FLOAT (32-bit) channels named
    ``<layer_name>.<pass>.<letter>`` with ZIP compression, as Blender 5 writes them; parent
    directories are created. NaN and Inf pixels are written as they are.

    Parameters
    ----------
    path : str or os.PathLike
    layers : dict of str -> (h, w, c) or (h, w) float
        Pass name (e.g. ``"Combined"``, ``"Variance"``, ``"Sample Count"``) to pixels, row 0
        at the bottom. All passes share ``(h, w)``; ``c`` is 1 to 4.
    layer_name : str
        The view layer's name.
    channel_ids : dict of str -> str, optional
        Channel letters per pass, overriding :data:`BLENDER_PASS_CHANNELS` and the defaults
        (``X``, ``XY``, ``RGB``, ``RGBA`` by channel count).
    metadata : dict of str -> str, optional
        Extra string attributes for the first part's header (Blender puts render metadata
        such as ``RenderTime`` there).

    Raises
    ------
    ValueError, TypeError
        For invalid passes, before anything is written.
    """
    _check_name("layer", layer_name)
    prepared = _prepare_layers(layers, channel_ids)
    OpenEXR = _openexr()
    extra = {str(k): str(v) for k, v in (metadata or {}).items()}
    parts = []
    for i, (name, chans, pixels) in enumerate(prepared):
        part_name = f"{layer_name}.{name}"
        header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
        if i == 0:
            header["BlenderMultiChannel"] = "Blender V2.55.1 and newer"
            header.update(extra)
        channels = {f"{part_name}.{c}": np.ascontiguousarray(pixels[:, :, k])
                    for k, c in enumerate(chans)}
        parts.append(OpenEXR.Part(header, channels, part_name))
    exr_file = OpenEXR.File(parts)
    _atomic_write(path, exr_file.write)


def render_metadata(result):
    """Header attributes that say whether an image is the whole render.

    ``samplingLab.partial`` is ``"true"`` for a render that was cancelled (Esc, Ctrl-C) or
    failed before its sample count or time limit, ``"false"`` for a complete one (a failed
    one also has ``samplingLab.error``, the error);
    ``samplingLab.spp`` is the samples per pixel of every finished pass and
    ``samplingLab.samples`` the camera samples taken (a cancelled render keeps the work units
    it finished beyond its last pass, so pixels may hold more than ``spp``: the Sample Count
    pass says how many).

    Parameters
    ----------
    result : core.render.RenderResult

    Returns
    -------
    dict of str to str
        For :func:`write_multilayer`'s ``metadata``.
    """
    metadata = {"samplingLab.partial": "true" if result.cancelled else "false",
                "samplingLab.spp": str(int(result.stats.get("spp", 0))),
                "samplingLab.samples": str(int(result.stats.get("samples", 0)))}
    if result.error:
        metadata["samplingLab.error"] = result.error
    return metadata


def read_metadata(path):
    """String attributes of the first part's header of the EXR at ``path`` (what
    :func:`write_multilayer` wrote as ``metadata``, and Blender's own, e.g. ``RenderTime``)."""
    OpenEXR = _openexr()
    with OpenEXR.File(str(path), separate_channels=True) as f:
        return {k: v for k, v in f.parts[0].header.items() if isinstance(v, str)}


def _split_channel(full):
    """``"Layer.Pass.R"`` -> ``("Layer", "Pass", "R")`` (the layer may itself contain dots)."""
    pieces = full.rsplit(".", 2)
    if len(pieces) == 3:
        return pieces[0], pieces[1], pieces[2]
    if len(pieces) == 2:
        return "", pieces[0], pieces[1]
    # A plain single-layer EXR (R, G, B, A): Blender shows it as the Combined pass.
    return "", "Combined", pieces[0]


def read_multilayer(path):
    """Read a multilayer OpenEXR file (Blender's or :func:`write_multilayer`'s) into passes.

    Channels are grouped by their ``<layer>.<pass>.`` prefix across all parts, ordered
    R, G, B, A / X, Y, Z, W / U, V, A within a pass, converted to float32 and flipped so that
    row 0 is the bottom row. Channels without a layer prefix (a plain RGBA EXR) form the pass
    ``"Combined"``.

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    dict of str -> (h, w, c) float32
        Keyed by pass name when the file holds one view layer, else by ``"<layer>.<pass>"``.
    """
    OpenEXR = _openexr()
    exr_file = OpenEXR.File(os.fspath(path), separate_channels=True)
    groups = {}
    for part in exr_file.parts:
        for full, channel in part.channels.items():
            if channel.xSampling != 1 or channel.ySampling != 1:
                raise ValueError(f"{path}: channel {full!r} is subsampled, which is unsupported")
            layer, pass_name, letter = _split_channel(full)
            groups.setdefault((layer, pass_name), {})[letter] = channel.pixels
    layer_names = {layer for layer, _ in groups}
    out = {}
    for (layer, pass_name), chans in groups.items():
        letters = sorted(chans, key=lambda c: (_CHANNEL_RANK.get(c, len(_CHANNEL_RANK)), c))
        pixels = np.stack([np.asarray(chans[c], np.float32) for c in letters], axis=-1)
        key = pass_name if len(layer_names) == 1 or not layer else f"{layer}.{pass_name}"
        out[key] = np.ascontiguousarray(pixels[::-1])
    return out


# --------------------------------------------------------------------------------------------
# PNG preview
# --------------------------------------------------------------------------------------------


def srgb_oetf(linear):
    """The sRGB transfer function (IEC 61966-2-1) on values in [0, 1]. ``(...)`` -> ``(...)``."""
    x = np.asarray(linear, np.float64)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(np.maximum(x, 0.0031308),
                                                                1.0 / 2.4) - 0.055)


def _png_chunk(kind, data):
    return (struct.pack(">I", len(data)) + kind + data
            + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))


def write_png_preview(path, rgb, exposure=0.0):
    """Write an 8-bit sRGB PNG preview of a linear image, atomically.

    Pixels are scaled by ``2**exposure``, NaN becomes 0, values are clamped to [0, 1], encoded
    with the sRGB OETF and rounded to 8 bits. No tone mapping: this is a preview, not Blender's
    view transform. The file carries an ``sRGB`` chunk.

    Parameters
    ----------
    path : str or os.PathLike
    rgb : (h, w, 3), (h, w, 4), (h, w, 1) or (h, w) float
        Linear Rec.709 pixels, row 0 at the bottom. Alpha, if present, is dropped; one channel
        gives a grey-scale PNG.
    exposure : float
        Stops.
    """
    a = np.asarray(rgb)
    if not (np.issubdtype(a.dtype, np.floating) or np.issubdtype(a.dtype, np.integer)):
        raise TypeError(f"pixels must be numeric, got dtype {a.dtype}")
    if a.ndim == 2:
        a = a[:, :, None]
    if a.ndim != 3 or a.shape[2] not in (1, 3, 4) or a.shape[0] < 1 or a.shape[1] < 1:
        raise ValueError(f"expected an (h, w, 1|3|4) image, got shape {np.shape(rgb)}")
    a = a[:, :, :3] if a.shape[2] == 4 else a
    h, w, c = a.shape
    scaled = np.nan_to_num(a.astype(np.float64) * (2.0 ** float(exposure)), nan=0.0,
                           posinf=1.0, neginf=0.0)
    encoded = srgb_oetf(np.clip(scaled, 0.0, 1.0))
    pixels = np.rint(encoded * 255.0).astype(np.uint8)[::-1]  # PNG rows run top to bottom
    # Each scanline starts with filter type 0 (None).
    raw = np.concatenate([np.zeros((h, 1), np.uint8), pixels.reshape(h, w * c)], axis=1)
    color_type = 0 if c == 1 else 2
    png = b"".join([
        b"\x89PNG\r\n\x1a\n",
        _png_chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, color_type, 0, 0, 0)),
        _png_chunk(b"sRGB", b"\x00"),
        _png_chunk(b"IDAT", zlib.compress(raw.tobytes(), 6)),
        _png_chunk(b"IEND", b""),
    ])
    _atomic_write(path, lambda f: f.write(png))
