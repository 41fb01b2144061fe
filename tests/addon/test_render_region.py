"""Render Region (``use_border``) in Blender: only the region's pixels are rendered.

The engine traces the region's pixels only, with sample streams indexed by frame pixel, so a
region's pixels are bit-identical to the same pixels of a full-frame render with the same seed,
whether Blender crops the output to the region or places it in a full-size frame.
"""

import numpy as np
import pytest

import scenes

# Border (min_x, max_x, min_y, max_y) of a 16 x 16 frame and the rows and columns Blender makes
# of it (corners truncated to whole pixels, y from the bottom).
BORDERS = [
    ((0.25, 0.75, 0.5, 1.0), slice(8, 16), slice(4, 12)),
    ((0.33, 0.71, 0.17, 0.93), slice(2, 14), slice(5, 11)),
]


def _set_border(scene, border, crop):
    render = scene.render
    render.use_border, render.use_crop_to_border = True, crop
    render.border_min_x, render.border_max_x, render.border_min_y, render.border_max_y = border


@pytest.mark.parametrize("border,rows,cols", BORDERS)
def test_cropped_region_equals_the_full_frame_pixels(empty_scene, tmp_path, capfd, border, rows,
                                                     cols):
    scenes.cornell_box_mesh_light(empty_scene, resolution=(16, 16))
    scenes.set_sampling_lab(empty_scene, samples=3, seed=3)
    full = scenes.render_to_exr(empty_scene, tmp_path / "full.exr")
    capfd.readouterr()
    _set_border(empty_scene, border, crop=True)
    crop = scenes.render_to_exr(empty_scene, tmp_path / "crop.exr")
    for name in ("Combined", "Variance", "Sample Count"):
        assert crop[name].shape[:2] == (rows.stop - rows.start, cols.stop - cols.start)
        np.testing.assert_array_equal(crop[name], full[name][rows, cols], err_msg=name)
    assert crop["Combined"][..., :3].mean() > 0
    # Only the region was traced: its camera samples are its pixels times the spp.
    n = (rows.stop - rows.start) * (cols.stop - cols.start)
    assert f"{n * 3} samples" in capfd.readouterr().out


@pytest.mark.parametrize("border,rows,cols", BORDERS)
def test_uncropped_region_fills_only_the_region_of_the_full_frame(empty_scene, tmp_path, border,
                                                                  rows, cols):
    scenes.cornell_box_mesh_light(empty_scene, resolution=(16, 16))
    scenes.set_sampling_lab(empty_scene, samples=2, seed=4)
    full = scenes.render_to_exr(empty_scene, tmp_path / "full.exr")["Combined"]
    _set_border(empty_scene, border, crop=False)
    out = scenes.render_to_exr(empty_scene, tmp_path / "uncropped.exr")["Combined"]
    assert out.shape == full.shape
    np.testing.assert_array_equal(out[rows, cols], full[rows, cols])
    outside = np.ones(out.shape[:2], bool)
    outside[rows, cols] = False
    np.testing.assert_array_equal(out[outside][:, :3], 0.0)
