"""EXR and PNG files: exact float32 round trips, Blender's channel naming and row order, atomic
writes, and valid PNG previews."""

from __future__ import annotations

import os
import struct
import zlib

import numpy as np
import OpenEXR
import pytest

from sampling_lab.core import exr

# Channel and part names of a multilayer EXR written by Blender 5.0.1 (Cycles, 8x8, with Depth,
# Normal, Mist and a value AOV enabled), inspected with OpenEXR.File(..., separate_channels=True).
# Blender writes one part per pass, named "<view layer>.<pass>".
BLENDER_COMBINED = {"ViewLayer.Combined.R", "ViewLayer.Combined.G", "ViewLayer.Combined.B",
                    "ViewLayer.Combined.A"}
BLENDER_DEPTH = {"ViewLayer.Depth.Z"}
BLENDER_NORMAL = {"ViewLayer.Normal.X", "ViewLayer.Normal.Y", "ViewLayer.Normal.Z"}
BLENDER_VALUE_AOV = {"ViewLayer.myval.X"}


def _passes(h=5, w=7, seed=0):
    rng = np.random.default_rng(seed)
    return {
        "Combined": rng.normal(size=(h, w, 4)).astype(np.float32),
        "Variance": rng.random((h, w, 3)).astype(np.float32),
        "Sample Count": rng.integers(0, 1000, (h, w, 1)).astype(np.float32),
        "Depth": rng.random((h, w, 1)).astype(np.float32) * 100,
    }


def _raw_channels(path):
    """{part name: {channel name: (h, w) pixels as stored, top row first}}."""
    f = OpenEXR.File(str(path), separate_channels=True)
    return {p.name(): {k: c.pixels for k, c in p.channels.items()} for p in f.parts}


def _leftovers(directory):
    return [n for n in os.listdir(directory) if n.endswith(".tmp")]


# --------------------------------------------------------------------------------------------
# Round trips, naming, orientation
# --------------------------------------------------------------------------------------------


def test_round_trip_is_bit_exact_for_float32(tmp_path):
    layers = _passes()
    special = layers["Combined"]
    special[0, 0] = [np.nan, np.inf, -np.inf, -0.0]
    special[1, 1] = [np.finfo(np.float32).tiny / 8, np.finfo(np.float32).max, 1e-45, -1e-38]
    path = tmp_path / "out.exr"
    exr.write_multilayer(path, layers)
    back = exr.read_multilayer(path)
    assert set(back) == set(layers)
    for name, a in layers.items():
        assert back[name].dtype == np.float32 and back[name].shape == a.shape
        np.testing.assert_array_equal(back[name].view(np.uint32), a.view(np.uint32), err_msg=name)


def test_rows_are_stored_top_first_and_read_back_bottom_first(tmp_path):
    h, w = 6, 3
    rows = np.repeat(np.arange(h, dtype=np.float32)[:, None, None], w, axis=1)  # value = row
    path = tmp_path / "rows.exr"
    exr.write_multilayer(path, {"Combined": np.repeat(rows, 4, axis=2), "Sample Count": rows})
    stored = _raw_channels(path)["ViewLayer.Sample Count"]["ViewLayer.Sample Count.X"]
    # Our row 0 (bottom) is the last scanline in the file; the first scanline is the top row.
    np.testing.assert_array_equal(stored[:, 0], np.arange(h)[::-1])
    back = exr.read_multilayer(path)
    np.testing.assert_array_equal(back["Sample Count"][:, 0, 0], np.arange(h))
    np.testing.assert_array_equal(back["Combined"][:, 0, 2], np.arange(h))


def test_channel_and_part_names_follow_blender_multilayer_naming(tmp_path):
    path = tmp_path / "names.exr"
    layers = _passes()
    layers["Normal"] = np.zeros((5, 7, 3), np.float32)
    layers["myval"] = np.zeros((5, 7), np.float32)
    exr.write_multilayer(path, layers)
    raw = _raw_channels(path)
    assert set(raw["ViewLayer.Combined"]) == BLENDER_COMBINED
    assert set(raw["ViewLayer.Depth"]) == BLENDER_DEPTH
    assert set(raw["ViewLayer.Normal"]) == BLENDER_NORMAL
    assert set(raw["ViewLayer.myval"]) == BLENDER_VALUE_AOV
    assert set(raw["ViewLayer.Variance"]) == {"ViewLayer.Variance.R", "ViewLayer.Variance.G",
                                              "ViewLayer.Variance.B"}
    assert set(raw["ViewLayer.Sample Count"]) == {"ViewLayer.Sample Count.X"}
    # Combined comes first, as in Blender's files.
    assert OpenEXR.File(str(path), header_only=True).parts[0].name() == "ViewLayer.Combined"


def test_header_declares_float_pixels_and_zip_compression(tmp_path):
    path = tmp_path / "hdr.exr"
    exr.write_multilayer(path, _passes(), metadata={"RenderTime": "00:01.00"})
    f = OpenEXR.File(str(path), separate_channels=True)
    for part in f.parts:
        assert part.header["compression"] == OpenEXR.ZIP_COMPRESSION
        assert all(c.pixels.dtype == np.float32 for c in part.channels.values())
    assert f.parts[0].header["RenderTime"] == "00:01.00"
    assert "BlenderMultiChannel" in f.parts[0].header


def test_custom_layer_name_and_channel_ids(tmp_path):
    path = tmp_path / "custom.exr"
    a = np.arange(2 * 3 * 2, dtype=np.float32).reshape(2, 3, 2)
    exr.write_multilayer(path, {"UVish": a}, layer_name="Render Layer", channel_ids={"UVish": "UV"})
    assert set(_raw_channels(path)["Render Layer.UVish"]) == {"Render Layer.UVish.U",
                                                             "Render Layer.UVish.V"}
    np.testing.assert_array_equal(exr.read_multilayer(path)["UVish"], a)


def test_reads_single_part_files_with_channels_in_storage_order_and_half_floats(tmp_path):
    # Blender 4.x wrote all passes into one part; channels come back in alphabetical order
    # from OpenEXR, and must be reordered R, G, B, A and X, Y, Z.
    h, w = 4, 5
    rng = np.random.default_rng(1)
    rgba = rng.random((h, w, 4)).astype(np.float32)
    normal = rng.random((h, w, 3)).astype(np.float16)
    channels = {f"ViewLayer.Combined.{c}": rgba[::-1, :, i].copy() for i, c in enumerate("RGBA")}
    channels.update({f"ViewLayer.Normal.{c}": normal[::-1, :, i].copy()
                     for i, c in enumerate("XYZ")})
    path = tmp_path / "single.exr"
    OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage},
                 channels).write(str(path))
    back = exr.read_multilayer(path)
    np.testing.assert_array_equal(back["Combined"], rgba)
    assert back["Normal"].dtype == np.float32
    np.testing.assert_array_equal(back["Normal"], normal.astype(np.float32))


def test_multiple_view_layers_are_keyed_by_layer_and_pass(tmp_path):
    a = np.ones((2, 2), np.float32)
    channels = {"Front.Combined.R": a, "Back.Combined.R": 2 * a, "Back.Depth.Z": 3 * a}
    path = tmp_path / "two.exr"
    OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage},
                 channels).write(str(path))
    back = exr.read_multilayer(path)
    assert set(back) == {"Front.Combined", "Back.Combined", "Back.Depth"}
    assert back["Back.Depth"].shape == (2, 2, 1) and back["Back.Depth"][0, 0, 0] == 3


def test_plain_rgba_exr_reads_as_the_combined_pass(tmp_path):
    rgb = np.random.default_rng(2).random((3, 4, 3)).astype(np.float32)
    path = tmp_path / "plain.exr"
    OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage},
                 {c: rgb[::-1, :, i].copy() for i, c in enumerate("RGB")}).write(str(path))
    np.testing.assert_array_equal(exr.read_multilayer(path)["Combined"], rgb)


def test_write_creates_parent_directories_and_replaces_existing_files(tmp_path):
    path = tmp_path / "a" / "b" / "c.exr"
    exr.write_multilayer(path, {"Combined": np.zeros((2, 2, 4), np.float32)})
    exr.write_multilayer(path, {"Combined": np.ones((3, 2, 4), np.float32)})
    assert exr.read_multilayer(path)["Combined"].shape == (3, 2, 4)
    assert _leftovers(path.parent) == []


# --------------------------------------------------------------------------------------------
# Atomicity
# --------------------------------------------------------------------------------------------


BAD_LAYERS = {
    "object pixels": {"Combined": np.array([[object()]], dtype=object)},
    "mismatched sizes": {"Combined": np.zeros((4, 4, 4)), "Depth": np.zeros((3, 4))},
    "five channels": {"Weird": np.zeros((2, 2, 5))},
    "dotted pass name": {"A.B": np.zeros((2, 2, 3))},
    "not a dict": [np.zeros((2, 2, 3))],
    "empty": {},
}


@pytest.mark.parametrize("case", list(BAD_LAYERS))
def test_invalid_layers_raise_and_leave_the_previous_file_intact(tmp_path, case):
    path = tmp_path / "keep.exr"
    exr.write_multilayer(path, {"Combined": np.full((2, 2, 4), 7, np.float32)})
    before = path.read_bytes()
    with pytest.raises((ValueError, TypeError)):
        exr.write_multilayer(path, BAD_LAYERS[case])
    assert path.read_bytes() == before
    assert _leftovers(tmp_path) == []


def test_failure_mid_write_leaves_the_previous_file_and_no_temp_file(tmp_path, monkeypatch):
    path = tmp_path / "keep.exr"
    exr.write_multilayer(path, {"Combined": np.full((2, 2, 4), 7, np.float32)})
    before = path.read_bytes()
    seen = {}

    def failing_fsync(fd):
        # The new file's bytes are on disk under the temporary name when this fails.
        seen["size"] = os.fstat(fd).st_size
        seen["tmp"] = _leftovers(tmp_path)
        raise OSError("disk full")

    monkeypatch.setattr(exr.os, "fsync", failing_fsync)
    with pytest.raises(OSError, match="disk full"):
        exr.write_multilayer(path, _passes(h=64, w=64))
    with pytest.raises(OSError, match="disk full"):
        exr.write_png_preview(tmp_path / "keep.png", np.zeros((4, 4, 3)))
    assert seen["size"] > 0 and len(seen["tmp"]) == 1
    assert path.read_bytes() == before
    assert _leftovers(tmp_path) == []
    assert not (tmp_path / "keep.png").exists()


def test_written_files_get_the_usual_permissions(tmp_path):
    path = tmp_path / "perm.exr"
    exr.write_multilayer(path, {"Combined": np.zeros((2, 2, 4), np.float32)})
    umask = os.umask(0)
    os.umask(umask)
    assert (path.stat().st_mode & 0o777) == (0o666 & ~umask)


# --------------------------------------------------------------------------------------------
# PNG preview
# --------------------------------------------------------------------------------------------


def _decode_png(data):
    """Parse chunks (checking CRCs) and return (IHDR fields, chunk types, (h, w, c) uint8)."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, chunks = 8, []
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos:pos + 4])
        kind, body = data[pos + 4:pos + 8], data[pos + 8:pos + 8 + length]
        (crc,) = struct.unpack(">I", data[pos + 8 + length:pos + 12 + length])
        assert crc == zlib.crc32(kind + body) & 0xFFFFFFFF, kind
        chunks.append((kind, body))
        pos += 12 + length
    kinds = [k for k, _ in chunks]
    assert kinds[0] == b"IHDR" and kinds[-1] == b"IEND"
    w, h, depth, color, comp, filt, interlace = struct.unpack(">IIBBBBB", chunks[0][1])
    c = {0: 1, 2: 3}[color]
    raw = zlib.decompress(b"".join(b for k, b in chunks if k == b"IDAT"))
    rows = np.frombuffer(raw, np.uint8).reshape(h, 1 + w * c)
    assert np.all(rows[:, 0] == 0)  # filter type None
    return (w, h, depth, color, comp, filt, interlace), kinds, rows[:, 1:].reshape(h, w, c)


def test_png_preview_has_a_valid_header_size_and_decodable_pixels(tmp_path):
    img = np.zeros((3, 5, 3), np.float32)
    img[0] = [1.0, 0.5, 0.0031308]          # bottom row
    img[1] = [2.0, -1.0, np.nan]             # clamped, clamped, NaN -> 0
    img[2, :, 0] = np.linspace(0, 1, 5)      # top row: a ramp in red
    path = tmp_path / "p" / "preview.png"
    exr.write_png_preview(path, img)
    ihdr, kinds, px = _decode_png(path.read_bytes())
    assert ihdr == (5, 3, 8, 2, 0, 0, 0)
    assert b"sRGB" in kinds
    # PNG rows run top to bottom, so our bottom row is the last one.
    np.testing.assert_array_equal(px[2, 0], [255, 188, 10])  # sRGB(0.5) = 0.7354 -> 187.5 -> 188
    np.testing.assert_array_equal(px[1, 0], [255, 0, 0])
    want = np.rint(255 * exr.srgb_oetf(np.linspace(0, 1, 5)))
    np.testing.assert_array_equal(px[0, :, 0], want)
    assert _leftovers(path.parent) == []


def test_png_preview_exposure_scales_by_powers_of_two(tmp_path):
    img = np.full((2, 2, 4), 0.25, np.float32)  # alpha is dropped
    exr.write_png_preview(tmp_path / "e.png", img, exposure=1)
    _, _, px = _decode_png((tmp_path / "e.png").read_bytes())
    assert px.shape == (2, 2, 3)
    assert np.all(px == np.rint(255 * exr.srgb_oetf(0.5)))


def test_png_preview_of_one_channel_is_greyscale(tmp_path):
    exr.write_png_preview(tmp_path / "g.png", np.full((4, 2), 1.0))
    ihdr, _, px = _decode_png((tmp_path / "g.png").read_bytes())
    assert ihdr[:4] == (2, 4, 8, 0) and np.all(px == 255)


def test_srgb_oetf_is_continuous_and_hits_its_end_points():
    assert exr.srgb_oetf(0.0) == 0.0
    assert exr.srgb_oetf(1.0) == pytest.approx(1.0, abs=1e-12)
    knee = 0.0031308
    assert exr.srgb_oetf(knee) == pytest.approx(1.055 * knee ** (1 / 2.4) - 0.055, abs=1e-7)
    assert np.all(np.diff(exr.srgb_oetf(np.linspace(0, 1, 10001))) > 0)
