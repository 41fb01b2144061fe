"""The Sampler Lab operator measures every sampler from inside Blender."""

import bpy
import pytest

from sampling_lab.core.sampling.samplers import available


def test_sampler_lab_operator_writes_the_table_and_plots(empty_scene, tmp_path):
    result = bpy.ops.samplinglab.sampler_lab(directory=str(tmp_path), points=64, quick=True)
    assert result == {'FINISHED'}
    table = (tmp_path / "SAMPLERS.md").read_text()
    for name in available():
        assert (tmp_path / f"points_{name}.csv").is_file(), name
    assert "independent" in table.lower()
    assert (tmp_path / "checkerboard.png").is_file()


def test_sampler_lab_operator_refuses_a_relative_folder_in_an_unsaved_file(empty_scene):
    with pytest.raises(RuntimeError, match="not saved"):
        bpy.ops.samplinglab.sampler_lab(directory="//lab", quick=True)
