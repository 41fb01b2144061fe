"""Randomly broken inputs for the fuzz harness (:mod:`.fuzz`): plain data, no ``bpy``.

A case is a JSON-able dict. Its ``route`` says how it runs (:mod:`.fuzz_child` carries it out):

- ``'blender'``: a Cornell box built with Blender's data API, broken by ``edits``, rendered by
  the engine inside Blender (``bpy.ops.render.render``);
- ``'blend'``: the same kind of broken scene saved as a ``.blend`` (perhaps then damaged on
  disk: ``damage``) and rendered by ``python -m sampling_lab render`` (``cli.main``);
- ``'cli'``: a built-in scene or a broken file through the command line with absurd flags.

An edit is ``[name, value]``; :data:`EDITS` lists the names and the values each draws from.
Values include NaN and infinities (JSON as Python writes it: ``NaN``, ``Infinity``).
"""

from __future__ import annotations

import random

NAN, INF = float("nan"), float("inf")
# Values that break a number: not a number, infinite, negative, zero, huge, tiny.
BAD = (NAN, INF, -INF, -1.0, 0.0, 1e30, 1e-30)

INTEGRATORS = ("path", "light", "bdpt", "photon", "sppm", "radiosity", "mlt")

# Scene edits (tools/fuzz_child.py applies them): name -> values.
EDITS = {
    "light_energy": BAD,
    "light_size": BAD,
    "light_color": BAD,
    "spot_size": BAD,
    "sun_angle": BAD,
    "emission_strength": BAD,
    "camera_lens": BAD,
    "camera_clip_start": BAD,
    "camera_clip_end": BAD,
    "camera_sensor": BAD,
    "camera_ortho_scale": BAD,
    "camera_shift": BAD,
    "object_scale": BAD,
    "object_location": BAD,
    "roughness": BAD,
    "ior": BAD,
    "base_color": BAD,
    "world_strength": BAD,
    "remove_output_node": (None,),
    "unlink_surface": (None,),
    "cyclic_nodes": (None,),
    "unknown_node": ("ShaderNodeHoldout", "ShaderNodeBsdfToon", "ShaderNodeBsdfHair",
                     "ShaderNodeVolumePrincipled", "ShaderNodeSubsurfaceScattering",
                     "ShaderNodeBsdfSheen", "ShaderNodeRGB", "ShaderNodeValue",
                     "ShaderNodeAddShader", "ShaderNodeMixShader"),
    "node_group": ("shader", "empty", "no_output", "none"),
    "missing_image": ("texture", "world"),
    "truncated_exr": ("texture", "world"),
    "image_without_file": ("texture", "world"),
    "empty_material_slot": (None,),
    "no_world": (None,),
    "no_camera": (None,),
    "no_lights": (None,),
    "samples": (0, 1 << 24),
    "time_limit": (-1.0, NAN, INF, 0.3),
    "resolution": ((65536, 65536), (1, 1), (0, 0), (12000, 12000), (1, 4000)),
    "nan_vertex": BAD,
    "empty_mesh": ("no_faces", "one_point", "collapsed"),
    "camera_type": ("PANO", "ORTHO"),
    "render_region": ((0.9, 0.1, 0.2, 0.8), (0.5, 0.5, 0.5, 0.5), (0.0, 0.01, 0.0, 0.01)),
    "frame": (-1000000, 1048574),
    "mix_fac": BAD,
    "volume_output": (None,),
    "sampler": ("independent", "stratified", "multijitter", "halton", "hammersley", "sobol",
                "pmj02", "poisson_disk", "lloyd", "cvt"),
    "threads": (1, 3, 64),
    "photon_memory": (1.0,),
    "radiosity_patch_size": (1e-3, 1e4),
}

# Ways to damage a saved .blend before the command line reads it.
DAMAGE = ("truncate", "garble", "empty", "magic_only")

# Command-line flags with absurd values: flag -> values (strings, as a user types them).
FLAGS = {
    "--spp": ("0", "-1", "1000000000", "nan", "abc", "1.5", "16777216"),
    "--time": ("-1", "nan", "inf", "0", "1e-9", "x", "0.3"),
    "--resolution": ("0x0", "-5x10", "100000x100000", "65536x65536", "1x1", "axb", "10x",
                     "12x10"),
    "--seed": ("-1", "2147483648", "x", "0"),
    "--threads": ("0", "-1", "100000", "1"),
    "--integrator": INTEGRATORS + ("nope",),
    "--mis": ("balance", "maximum", "bsdf", "light", "none", "veach"),
    "--light-selection": ("uniform", "tree", "power"),
    "--max-depth": ("0", "-1", "100000"),
    "--filter-width": ("0", "nan", "11"),
    "--photons": ("0", "1", "1000000000"),
    "--photon-memory": ("0", "1"),
    "--radiosity-patch-size": ("0.001", "nan"),
    "--mlt-large-step": ("-0.1", "nan", "0", "1"),
    "--mlt-bootstrap": ("0", "2"),
    "--mlt-chains": ("0", "1"),
    "--frame": ("-5", "x"),
    "--strategy-views": (None,),
    "--no-such-flag": (None,),
}

# The scene argument of a command-line case.
SCENE_ARGS = ("cornell",) * 8 + ("glass_caustic", "no_such_scene", "garbage.blend",
              "magic_garbage.blend", "empty.blend", "folder.blend", "missing.blend",
              "truncated.exr", "sub/dir/missing.blend")

# The output argument of a command-line or .blend case.
OUTPUTS = ("out.exr",) * 6 + ("new/deep/folder/out.exr", "a_file/out.exr",
           "folder.exr", "out.png", "readonly/out.exr", "/proc/sys/out.exr",
           "truncated.exr")

ROUTES = ("blender", "blend", "cli")


def _pick_edits(rng, k):
    names = rng.sample(sorted(EDITS), k)
    return [[name, rng.choice(EDITS[name])] for name in names]


def scene_case(rng, route):
    """A broken data-API scene: 1 to 3 edits, a random integrator, a tiny image."""
    case = {"route": route, "integrator": rng.choice(INTEGRATORS),
            "light": rng.choice(("area", "point", "mesh")),
            "edits": _pick_edits(rng, rng.randint(1, 3))}
    if route == "blend":
        # Mostly an intact file and a good output, so that the broken scene itself is read.
        case["damage"] = rng.choice(DAMAGE) if rng.random() < 0.4 else None
        case["output"] = rng.choice(OUTPUTS) if rng.random() < 0.3 else "out.exr"
    return case


def cli_case(rng):
    """A command line: a scene argument, an output, and 0 to 2 flags with absurd values."""
    flags = {"--resolution": "12x10", "--spp": "1"}
    for flag in rng.sample(sorted(FLAGS), rng.randint(0, 2)):
        flags[flag] = rng.choice(FLAGS[flag])
    if "--time" in flags and flags["--spp"] == "1":
        del flags["--spp"]  # (both given is refused by argparse: a fine case, but a dull one)
    argv = ["render", rng.choice(SCENE_ARGS), "-o", rng.choice(OUTPUTS), "--quiet"]
    for flag, value in flags.items():
        argv += [flag] if value is None else [flag, value]
    return {"route": "cli", "argv": argv}


def make_cases(count, seed):
    """``count`` cases from ``seed`` (the same pair gives the same cases); routes take turns so
    that any run of three consecutive cases covers all of them."""
    rng = random.Random(seed)
    cases = []
    for i in range(count):
        route = ROUTES[i % len(ROUTES)]
        case = cli_case(rng) if route == "cli" else scene_case(rng, route)
        case["id"] = i
        cases.append(case)
    return cases
