"""The release archive installs and renders the way Blender installs it.

``tools/dist.py`` builds the linux-x64 archive (cp311 wheels only, which is what this ``bpy``
runs; the wheels are cached under ``build/wheels/``, a fresh machine downloads them from PyPI).
A child process then installs it with ``bpy.ops.extensions.package_install_files`` into a fresh
user repository under a temporary ``BLENDER_USER_RESOURCES``. The child runs the venv's Python
with ``-S`` (no site-packages) and a ``PYTHONPATH`` holding only links to ``bpy`` and numpy (which
Blender ships), so ``embreex``, ``OpenEXR`` and ``scipy`` can only come from the archive's wheels; it checks
that they cannot be imported before the install. This process already imported ``bpy`` with the
working tree's add-on enabled (conftest.py), hence the child.

The install child enables the add-on, applies every shipped preset from the Sampling presets
menu's folders, adds a user preset, renders a small Cornell box to a multilayer EXR, disables
the add-on (checking that nothing of it stays registered), enables it again, disables it and
uninstalls it. It prints one JSON line of what it saw; the tests read the EXR back.

A second child enables the working tree as a local repository in the same isolated Python (no
wheels anywhere): enabling works, and a render stops with one error that names ``embreex``.
"""

import json
import os
import subprocess
import sys
import textwrap
import zipfile
from importlib.metadata import distribution
from pathlib import Path

import numpy as np
import pytest

from scenes import REPO_ROOT, read_blender_exr

from sampling_lab.addon.passes import PASSES


def _load_dist():
    """tools/dist.py (tools/ is not a package, and the archive excludes it)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("sampling_lab_tools_dist",
                                                  REPO_ROOT / "tools" / "dist.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


dist = _load_dist()

SHIPPED_PRESETS = sorted(p.stem for p in (REPO_ROOT / "presets" / "sampling_lab" / "sampling")
                         .glob("*.py"))
SIZE, SPP = 16, 2

# Shared by both children: argv is (archive or source folder, EXR path); what they saw goes into
# `seen`, printed as one JSON line at the end.
PRELUDE = textwrap.dedent(r'''
    import importlib, json, os, sys
    from pathlib import Path

    source, exr_path = sys.argv[1], sys.argv[2]
    SIZE, SPP = int(sys.argv[3]), int(sys.argv[4])
    user_res = os.environ["BLENDER_USER_RESOURCES"]
    seen = {"sys_path": list(sys.path)}

    def importable(name):
        try:
            module = importlib.import_module(name)
        except ImportError:
            return None
        return module.__file__

    # Only the archive's wheels may provide these.
    seen["before"] = {m: importable(m) for m in ("embreex", "OpenEXR", "scipy",
                                                 "sampling_lab")}

    import bpy
    import addon_utils

    ENGINE = "SAMPLING_LAB"

    def engines():
        found, stack = set(), list(bpy.types.RenderEngine.__subclasses__())
        while stack:
            cls = stack.pop()
            stack.extend(cls.__subclasses__())
            # Unregistered classes stay subclasses while Python holds them.
            if getattr(cls, "is_registered", False):
                found.add(getattr(cls, "bl_idname", None))
        return found

    def cornell_box(scene):
        """A tiny Cornell box lit by an emissive quad, set to render a multilayer EXR."""
        def material(name, node_type, color, strength=None):
            mat = bpy.data.materials.new(name)
            mat.use_nodes = True
            nodes = mat.node_tree.nodes
            nodes.clear()
            out = nodes.new("ShaderNodeOutputMaterial")
            node = nodes.new(node_type)
            node.inputs["Color"].default_value = (*color, 1.0)
            if strength is not None:
                node.inputs["Strength"].default_value = strength
            mat.node_tree.links.new(node.outputs[0], out.inputs["Surface"])
            return mat

        def quad(name, corners, mat):
            mesh = bpy.data.meshes.new(name)
            mesh.from_pydata(corners, [], [(0, 1, 2, 3)])
            mesh.materials.append(mat)
            scene.collection.objects.link(bpy.data.objects.new(name, mesh))

        white = material("White", "ShaderNodeBsdfDiffuse", (0.8, 0.8, 0.8))
        red = material("Red", "ShaderNodeBsdfDiffuse", (0.6, 0.05, 0.05))
        green = material("Green", "ShaderNodeBsdfDiffuse", (0.1, 0.5, 0.1))
        lamp = material("Lamp", "ShaderNodeEmission", (1.0, 1.0, 1.0), strength=10.0)
        quad("Floor", [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], white)
        quad("Ceiling", [(-1, -1, 2), (-1, 1, 2), (1, 1, 2), (1, -1, 2)], white)
        quad("Back", [(-1, 1, 0), (1, 1, 0), (1, 1, 2), (-1, 1, 2)], white)
        quad("Left", [(-1, -1, 0), (-1, 1, 0), (-1, 1, 2), (-1, -1, 2)], red)
        quad("Right", [(1, -1, 0), (1, -1, 2), (1, 1, 2), (1, 1, 0)], green)
        quad("Lamp", [(-0.25, -0.25, 1.98), (0.25, -0.25, 1.98), (0.25, 0.25, 1.98),
                      (-0.25, 0.25, 1.98)], lamp)
        world = bpy.data.worlds.new("Black")
        world.color = (0.0, 0.0, 0.0)
        scene.world = world
        cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
        cam.data.lens = 38.0
        cam.location = (0.0, -3.9, 1.0)
        cam.rotation_euler = (1.5707963, 0.0, 0.0)
        scene.collection.objects.link(cam)
        scene.camera = cam
        scene.render.resolution_x = scene.render.resolution_y = SIZE
        scene.render.resolution_percentage = 100
        scene.render.engine = ENGINE
        settings = scene.sampling_lab
        settings.integrator, settings.sampler, settings.samples = "PATH", "INDEPENDENT", SPP
        image = scene.render.image_settings
        image.media_type = "MULTI_LAYER_IMAGE"
        image.file_format = "OPEN_EXR_MULTILAYER"
        image.color_depth = "32"
        scene.render.use_file_extension = False
        scene.render.filepath = exr_path
''')

INSTALL_CHILD = PRELUDE + textwrap.dedent(r'''
    MODULE = "bl_ext.user_default.sampling_lab"

    def leftovers():
        """What of the add-on is still registered."""
        left = []
        if ENGINE in engines():
            left.append("engine")
        if hasattr(bpy.types.Scene, "sampling_lab"):
            left.append("Scene.sampling_lab")
        for name in dir(bpy.app.handlers):
            handlers = getattr(bpy.app.handlers, name)
            if isinstance(handlers, list):
                left += [f"handler {name}: {h}" for h in handlers
                         if getattr(h, "__module__", "").startswith(MODULE)]
        left += [c for c in ("SAMPLINGLAB_MT_sampling_presets", "SAMPLINGLAB_RENDER_PT_sampling")
                 if hasattr(bpy.types, c)]
        return left

    result = bpy.ops.extensions.package_install_files(
        filepath=source, repo="user_default", enable_on_install=True)
    seen["install"] = sorted(result)
    seen["enabled"] = MODULE in {a.module for a in bpy.context.preferences.addons}
    seen["engine_registered"] = ENGINE in engines()
    seen["after"] = {m: importable(m) for m in ("embreex", "OpenEXR", "scipy.spatial")}
    seen["user_resources"] = user_res
    seen["addon_file"] = sys.modules[MODULE].__file__

    # The Sampling presets menu: the folders it lists and the presets in them.
    presets = importlib.import_module(MODULE + ".addon.presets")
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = ENGINE
    seen["menu_folders"] = presets.preset_paths()
    seen["menu"] = presets.preset_files()
    applied = {}
    for label, path in seen["menu"]:
        scene.sampling_lab.samples = 12345
        done = bpy.ops.script.execute_preset(filepath=path,
                                             menu_idname="SAMPLINGLAB_MT_sampling_presets")
        applied[Path(path).stem] = [sorted(done), scene.sampling_lab.samples]
    seen["applied"] = applied
    scene.sampling_lab.samples = 321
    seen["add_preset"] = sorted(bpy.ops.render.sampling_lab_preset_add(name="Install Test"))
    seen["menu_after_add"] = presets.preset_files()

    cornell_box(scene)
    seen["render"] = sorted(bpy.ops.render.render(write_still=True))

    # Disable: nothing of the add-on stays registered; enabling again works.
    addon_utils.disable(MODULE, default_set=True)
    seen["leftovers_after_disable"] = leftovers()
    errors = []
    module = addon_utils.enable(MODULE, default_set=True, handle_error=errors.append)
    seen["reenable_errors"] = [repr(e) for e in errors]
    seen["reenabled"] = module is not None and ENGINE in engines()
    addon_utils.disable(MODULE, default_set=True)

    # Uninstall: the extension's folder goes, and nothing stays registered.
    repo = next(r for r in bpy.context.preferences.extensions.repos if r.module == "user_default")
    seen["uninstall"] = sorted(bpy.ops.extensions.package_uninstall(
        repo_directory=repo.directory, pkg_id="sampling_lab"))
    seen["installed_after_uninstall"] = os.path.exists(os.path.join(repo.directory,
                                                                    "sampling_lab"))
    seen["enabled_after_uninstall"] = MODULE in {a.module for a in bpy.context.preferences.addons}
    seen["leftovers_after_uninstall"] = leftovers()
    print("RESULT " + json.dumps(seen), flush=True)
''')

SOURCE_CHILD = PRELUDE + textwrap.dedent(r'''
    # The working tree as a local extension repository (as conftest.py does): no wheels.
    repo_dir = Path(user_res) / "dev_repo"
    repo_dir.mkdir(parents=True)
    (repo_dir / "sampling_lab").symlink_to(source, target_is_directory=True)
    bpy.context.preferences.extensions.repos.new(
        name="dev", module="dev", custom_directory=str(repo_dir), source='USER')
    errors = []
    module = addon_utils.enable("bl_ext.dev.sampling_lab", default_set=True,
                                handle_error=errors.append)
    seen["enable_errors"] = [repr(e) for e in errors]
    seen["enabled"] = module is not None and ENGINE in engines()
    bpy.ops.wm.read_homefile(use_empty=True)
    cornell_box(bpy.context.scene)
    try:
        bpy.ops.render.render(write_still=True)
        seen["render_error"] = None
    except RuntimeError as exc:
        seen["render_error"] = str(exc)
    seen["exr_written"] = os.path.exists(exr_path)
    print("RESULT " + json.dumps(seen), flush=True)
''')


def isolated_pythonpath(folder):
    """A folder with links to the bpy and numpy distributions only (Blender's own Python has
    numpy, not embreex or OpenEXR)."""
    folder.mkdir()
    for name in ("bpy", "numpy"):
        files = distribution(name)
        for top in sorted({Path(str(f)).parts[0] for f in files.files}):
            target = Path(files.locate_file(top))
            if top.endswith(".dist-info") or top in ("..", "bin") or not target.exists():
                continue
            (folder / top).symlink_to(target, target_is_directory=target.is_dir())
    return folder


def run_child(script, source, work):
    """Run ``script`` in the isolated Python with a fresh ``BLENDER_USER_RESOURCES``.

    Returns
    -------
    dict
        The child's JSON line, plus ``exr`` (the path it was told to write).
    """
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "VIRTUAL_ENV"))}
    env["PYTHONPATH"] = str(isolated_pythonpath(work / "path"))
    env["PYTHONNOUSERSITE"] = "1"
    env["BLENDER_USER_RESOURCES"] = str(work / "user")
    (work / "child.py").write_text(script)
    exr = work / "render.exr"
    command = [sys.executable, "-S", str(work / "child.py"), str(source), str(exr), str(SIZE),
               str(SPP)]
    proc = subprocess.run(command, cwd=work, env=env, capture_output=True, text=True, timeout=300)
    lines = [line for line in proc.stdout.splitlines() if line.startswith("RESULT ")]
    assert proc.returncode == 0 and lines, (proc.stdout[-4000:], proc.stderr[-4000:])
    seen = json.loads(lines[-1][len("RESULT "):])
    seen["exr"] = exr
    return seen


@pytest.fixture(scope="module")
def linux_archive(tmp_path_factory):
    """The linux-x64 archive with the cp311 wheels, built by tools/dist.py like ``./lab dist``."""
    out = tmp_path_factory.mktemp("dist")
    archives = dist.build(platforms=("linux-x64",), pythons=("cp311",), output=out / "dist",
                          stage_dir=out / "stage", quiet=True)
    return archives["linux-x64"]


@pytest.fixture(scope="module")
def installed(linux_archive, tmp_path_factory):
    """The install child's report: install, use, disable, re-enable and uninstall the archive."""
    return run_child(INSTALL_CHILD, linux_archive, tmp_path_factory.mktemp("install"))


def test_archive_holds_only_what_the_addon_needs(linux_archive):
    names = zipfile.ZipFile(linux_archive).namelist()
    tops = {n.split("/", 1)[0] for n in names}
    assert {"__init__.py", "blender_manifest.toml", "addon", "core", "presets", "wheels"} <= tops
    assert not tops & {"tests", "bench", "tools", "docs", ".venv", ".git", "build", "dist", "lab"}
    wheels = sorted(n for n in names if n.endswith(".whl"))
    assert [w.split("/")[1].split("-")[0].lower() for w in wheels] == ["embreex", "openexr",
                                                                       "scipy"]
    assert all("-cp311-" in w and "manylinux" in w for w in wheels)
    assert not [n for n in names if "numpy" in n.lower() or n.endswith(".pyc")]


def test_archive_manifest_lists_its_wheels_and_platform(linux_archive):
    import tomllib

    archive = zipfile.ZipFile(linux_archive)
    manifest = tomllib.loads(archive.read("blender_manifest.toml").decode())
    inside = sorted(n for n in archive.namelist() if n.endswith(".whl"))
    # tools/dist.py's generated lists, and the builder's per-archive [build.generated] table.
    assert manifest["platforms"] == ["linux-x64"]
    assert sorted(w.removeprefix("./") for w in manifest["wheels"]) == inside
    generated = manifest["build"]["generated"]
    assert generated["platforms"] == ["linux-x64"]
    assert sorted(w.removeprefix("./") for w in generated["wheels"]) == inside
    source = tomllib.loads((REPO_ROOT / "blender_manifest.toml").read_text())
    assert "wheels" not in source and "platforms" not in source


def test_child_sees_no_venv_modules_before_install(installed):
    assert installed["before"] == {"embreex": None, "OpenEXR": None, "scipy": None,
                                   "sampling_lab": None}
    assert not [p for p in installed["sys_path"] if "site-packages" in p]


def test_install_enables_the_engine_with_the_bundled_wheels(installed):
    assert installed["install"] == ["FINISHED"]
    assert installed["enabled"] and installed["engine_registered"]
    user = installed["user_resources"]
    assert installed["addon_file"].startswith(user)
    for module in ("embreex", "OpenEXR", "scipy.spatial"):
        assert installed["after"][module] and installed["after"][module].startswith(user), \
            installed["after"]


def test_presets_menu_lists_the_shipped_presets(installed):
    stems = sorted(Path(path).stem for _, path in installed["menu"])
    assert stems == SHIPPED_PRESETS
    assert all(path.startswith(installed["user_resources"]) for _, path in installed["menu"])
    assert installed["menu_folders"][0].endswith("presets/sampling_lab/sampling")
    for stem in SHIPPED_PRESETS:
        result, samples = installed["applied"][stem]
        assert result == ["FINISHED"] and samples != 12345, (stem, samples)


def test_add_preset_stores_a_user_preset(installed):
    assert installed["add_preset"] == ["FINISHED"]
    added = [(label, path) for label, path in installed["menu_after_add"]
             if Path(path).stem == "Install_Test"]
    assert len(added) == 1 and added[0][0] == "Install Test"
    assert Path(added[0][1]).is_relative_to(
        Path(installed["user_resources"]) / "scripts" / "presets")


def test_installed_engine_renders_every_pass(installed):
    assert installed["render"] == ["FINISHED"]
    passes = read_blender_exr(installed["exr"])
    for name, channels, _, _ in PASSES:
        image = passes[name]
        assert image.shape == (SIZE, SIZE, channels), (name, image.shape)
        assert np.isfinite(image).all(), name
        assert (image >= 0).all() and image.max() > 0, name
    assert np.all(passes["Sample Count"] == SPP)
    assert passes["Combined"][..., :3].mean() > 0.01


def test_disable_reenable_and_uninstall_leave_nothing_behind(installed):
    assert installed["leftovers_after_disable"] == []
    assert installed["reenable_errors"] == [] and installed["reenabled"]
    assert installed["uninstall"] == ["FINISHED"]
    assert not installed["installed_after_uninstall"]
    assert not installed["enabled_after_uninstall"]
    assert installed["leftovers_after_uninstall"] == []


def test_source_checkout_without_wheels_enables_and_names_the_missing_module(tmp_path):
    seen = run_child(SOURCE_CHILD, REPO_ROOT, tmp_path)
    assert seen["before"]["embreex"] is None
    assert seen["enable_errors"] == [] and seen["enabled"]
    error = seen["render_error"]
    assert error is not None and "embreex" in error
    assert error.count("Sampling Lab needs") == 1, error
    assert not seen["exr_written"]
