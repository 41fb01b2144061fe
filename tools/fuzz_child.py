"""The fuzz harness's child process: runs cases one after another and logs what each did.

``python -m sampling_lab.tools.fuzz_child CASES.json LOG.jsonl WORK_DIR`` runs the cases of
:mod:`.fuzz_cases` in order. Before a case it appends ``{"start": id}`` to the log, after it
``{"end": id, ...}`` with what happened; the parent (:mod:`.fuzz`) reads the log, so a crash or a
hang of one case is seen as a start without an end, and the parent restarts the child for the
cases left. Everything a case prints, Python or C (Blender's own messages), goes into a file of
its own (file descriptors 1 and 2 are redirected), and the log carries its text.

Scene edits are Blender data-API calls (:data:`EDITS`); an edit that Blender itself refuses
(its property ranges clamp or reject a value) is logged as skipped, not as a failure of ours.
"""

from __future__ import annotations

import contextlib
import json
import os
import random
import sys
import time
import traceback


RESOLUTION = (12, 10)


@contextlib.contextmanager
def captured(path):
    """File descriptors 1 and 2 (and Python's streams) into the file ``path``."""
    from ..addon.blendfile import fds_into

    with open(path, "wb") as out, fds_into(out):
        yield


def make_fixtures(folder):
    """The broken files a case may name: garbage and truncated files, a folder where a file is
    wanted, a file where a folder is wanted, a read-only folder."""
    import numpy as np

    from ..core.exr import write_multilayer

    os.makedirs(folder, exist_ok=True)
    rng = random.Random(0)
    junk = bytes(rng.randrange(256) for _ in range(4096))
    for name, data in (("garbage.blend", junk), ("magic_garbage.blend", b"BLENDER" + junk),
                       ("empty.blend", b""), ("a_file", b"a file where a folder is wanted\n")):
        with open(os.path.join(folder, name), "wb") as f:
            f.write(data)
    for name in ("folder.blend", "folder.exr", "readonly"):
        os.makedirs(os.path.join(folder, name), exist_ok=True)
    os.chmod(os.path.join(folder, "readonly"), 0o555)
    exr = os.path.join(folder, "truncated.exr")
    write_multilayer(exr, {"Combined": np.ones((8, 8, 4), np.float32)})
    with open(exr, "r+b") as f:
        f.truncate(os.path.getsize(exr) // 2)


def exr_state(path):
    """``'finite'``, ``'nonfinite'`` (NaN or Inf in a layer) or ``'none'`` (no readable EXR)."""
    from ..core.exr import read_multilayer

    try:
        layers = read_multilayer(path)
    except Exception:  # noqa: BLE001 - an unreadable output is an outcome, not a crash
        return "none"
    import numpy as np

    return "finite" if all(np.isfinite(a).all() for a in layers.values()) else "nonfinite"


def run_cli(argv, folder):
    """``cli.main(argv)`` in ``folder``: its exit code, or the exception that escaped it."""
    from ..cli import main

    os.chdir(folder)
    try:
        return {"code": main(list(argv))}
    except BaseException:  # noqa: BLE001 - an escaped exception is what the harness counts
        traceback.print_exc()
        return {"code": None, "raised": traceback.format_exc().strip().splitlines()[-1]}


def output_state(argv, folder, code):
    out = argv[argv.index("-o") + 1]
    path = out if os.path.isabs(out) else os.path.join(folder, out)
    return exr_state(path) if code in (0, 1, 130) else "none"


def build_scene(case, folder):
    """A Cornell box broken by the case's edits; returns the Blender scene and skipped edits."""
    import bpy

    from .bpy_scenes import cornell_box
    from .fuzz_edits import EDITS

    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "SAMPLING_LAB"
    objs = cornell_box(scene, case["light"], RESOLUTION)
    props = scene.sampling_lab
    props.integrator = case["integrator"].upper()
    props.samples = 1
    props.photons = 2000
    skipped = []
    for name, value in case["edits"]:
        try:
            EDITS[name](scene, objs, value, folder)
        except (TypeError, ValueError, AttributeError, KeyError, RuntimeError, ReferenceError,
                StopIteration) as exc:
            skipped.append(f"{name}: {type(exc).__name__}: {exc}")
    return scene, skipped


def run_blender(case, folder):
    """Render the broken scene with the engine inside Blender, to a multilayer EXR."""
    import bpy

    scene, skipped = build_scene(case, folder)
    out = os.path.join(folder, "blender.exr")
    settings = scene.render.image_settings
    settings.media_type = "MULTI_LAYER_IMAGE"
    settings.color_depth = "32"
    scene.render.use_file_extension = False
    scene.render.filepath = out
    record = {"skipped": skipped}
    try:
        bpy.ops.render.render(write_still=True, scene=scene.name)
        record["code"] = 0
    except RuntimeError as exc:
        record.update(code=2, message=str(exc).strip())
    except BaseException:  # noqa: BLE001
        traceback.print_exc()
        record.update(code=None, raised=traceback.format_exc().strip().splitlines()[-1])
    record["exr"] = exr_state(out) if record["code"] == 0 else "none"
    return record


def run_blend(case, folder):
    """Save the broken scene as a .blend, damage the file, render it with the command line."""
    import bpy

    from .fuzz_edits import apply_damage

    scene, skipped = build_scene(case, folder)
    blend = os.path.join(folder, "case.blend")
    with captured(os.path.join(folder, "save.txt")):  # (Blender's "Saved copy" line)
        bpy.ops.wm.save_as_mainfile(filepath=blend, copy=True)
    apply_damage(blend, case["damage"])
    argv = ["render", blend, "-o", case["output"], "--quiet"]
    record = run_cli(argv, folder)
    record.update(skipped=skipped, exr=output_state(argv, folder, record["code"]))
    return record


def run_selftest(case):
    """Fail on purpose (``case["fail"]``: ``'hang'``, ``'crash'`` or ``'traceback'``), so the
    tests can show that the harness counts each failure."""
    if case["fail"] == "hang":
        time.sleep(3600)
    if case["fail"] == "crash":
        os.abort()
    traceback.print_stack()
    print("Traceback (most recent call last): (a self-test)", file=sys.stderr)
    return {"code": 1, "exr": "none"}


def run_case(case, folder):
    if case["route"] == "selftest":
        return run_selftest(case)
    make_fixtures(folder)
    if case["route"] == "cli":
        record = run_cli(case["argv"], folder)
        record["exr"] = output_state(case["argv"], folder, record["code"])
        return record
    return (run_blender if case["route"] == "blender" else run_blend)(case, folder)


def enable_addon(work):
    """Enable the extension from this checkout (a temporary extension repository that holds one
    link to it), as Blender would after installing it."""
    import bpy
    import addon_utils  # (importable once bpy has set up its script paths)

    repo = os.path.join(work, "extensions")
    os.makedirs(repo, exist_ok=True)
    link = os.path.join(repo, "sampling_lab")
    if not os.path.islink(link):
        os.symlink(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), link)
    bpy.context.preferences.extensions.repos.new(
        name="sampling_lab_fuzz", module="sampling_lab_fuzz", custom_directory=repo,
        source="USER")
    if addon_utils.enable("bl_ext.sampling_lab_fuzz.sampling_lab", default_set=True) is None:
        raise RuntimeError("enabling the extension failed")


def main(cases_path, log_path, work):
    with open(cases_path) as f:
        cases = json.load(f)
    if any(c["route"] not in ("cli", "selftest") for c in cases):
        os.environ.setdefault("BLENDER_USER_RESOURCES", os.path.join(work, "blender_user"))
        enable_addon(work)
    with open(log_path, "a") as log:
        for case in cases:
            log.write(json.dumps({"start": case["id"]}) + "\n")
            log.flush()
            folder = os.path.join(work, f"case{case['id']}")
            text_path = os.path.join(work, f"case{case['id']}.txt")
            with captured(text_path):
                try:
                    record = run_case(case, folder)
                except Exception:  # noqa: BLE001 - the harness's own failure, counted apart
                    traceback.print_exc()
                    record = {"code": None, "harness_error": traceback.format_exc()[-2000:]}
            with open(text_path, "rb") as f:
                record["text"] = f.read().decode(errors="replace")[-4000:]
            log.write(json.dumps({"end": case["id"], **record}) + "\n")
            log.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:4]))
