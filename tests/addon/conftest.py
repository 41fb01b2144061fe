"""Fixtures for tests that drive the real ``bpy`` module with the add-on enabled.

Blender's user resources (preferences, extension repositories) are redirected to a temporary
folder *before* ``bpy`` is imported, so the tests never read or write the developer's own
Blender configuration. The add-on is enabled as an extension straight from the working tree: a
temporary extension repository holds one symbolic link, ``sampling_lab`` -> the repository root.

Fixtures
--------
addon (session)
    Enables the extension once; yields its module (``bl_ext.sampling_lab_dev.sampling_lab``).
empty_scene (function)
    Loads an empty file, selects the Sampling Lab engine, yields ``bpy.context.scene``.
export (session)
    The add-on's ``addon.export`` module (``export.export_scene(depsgraph)``).
"""

import importlib
import os
import sys
import tempfile
from pathlib import Path

_USER_RESOURCES = tempfile.mkdtemp(prefix="sampling_lab_blender_user_")
os.environ["BLENDER_USER_RESOURCES"] = _USER_RESOURCES

import bpy  # noqa: E402  (after BLENDER_USER_RESOURCES)
import addon_utils  # noqa: E402  (importable once bpy has set up its script paths)
import pytest  # noqa: E402

# Make tests/addon importable (scenes.py) whatever pytest's import mode.
sys.path.insert(0, str(Path(__file__).resolve().parent))

from scenes import ADDON_MODULE, ENGINE_ID, EXTENSION_REPO, REPO_ROOT, registered_engines  # noqa: E402


@pytest.fixture(scope="session")
def addon(tmp_path_factory):
    """Enable the Sampling Lab extension from the working tree for the whole session."""
    repo_dir = tmp_path_factory.mktemp("extensions")
    (repo_dir / "sampling_lab").symlink_to(REPO_ROOT, target_is_directory=True)
    repos = bpy.context.preferences.extensions.repos
    repos.new(name=EXTENSION_REPO, module=EXTENSION_REPO, custom_directory=str(repo_dir),
              source='USER')
    module = addon_utils.enable(ADDON_MODULE, default_set=True)
    assert module is not None, f"enabling {ADDON_MODULE} failed (see the traceback above)"
    assert ENGINE_ID in registered_engines()
    yield module
    # The repository stays (it lives in the temporary user resources): removing it would make
    # Blender disable the add-on a second time.
    addon_utils.disable(ADDON_MODULE, default_set=True)


@pytest.fixture(scope="session")
def export(addon):
    """The add-on's exporter module, as Blender imported it."""
    return importlib.import_module(f"{ADDON_MODULE}.addon.export")


@pytest.fixture()
def empty_scene(addon):
    """A new empty file (the add-on stays enabled) with the Sampling Lab engine selected."""
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = ENGINE_ID
    return scene


@pytest.fixture()
def pass_counts(addon, monkeypatch):
    """The mean Sample Count of every progressive update the engine writes to Blender, in
    order (a list that fills as a render runs; updates are not throttled)."""
    from importlib import import_module
    engine = import_module(f"{addon.__name__}.addon.engine")
    monkeypatch.setattr(engine, "UPDATE_INTERVAL", 0.0)
    write_passes = engine.passes.write_passes
    counts = []

    def recording(layer, images):
        counts.append(float(images["Sample Count"].mean()))
        write_passes(layer, images)

    monkeypatch.setattr(engine.passes, "write_passes", recording)
    return counts
