"""Release archives: one Blender extension archive per platform, with the wheels it needs.

``./lab dist`` runs this script. It

1. downloads the pinned wheels of the modules the renderer needs besides Blender's own numpy
   (:data:`BUNDLED`, versions from ``requirements.txt``) for every platform and Python of
   :data:`PLATFORMS` and :data:`PYTHONS` into ``build/wheels/<platform>/<python>/``; a wheel
   already there is not downloaded again;
2. stages the repository's files (those git does not ignore) in ``build/stage/`` with a generated
   ``blender_manifest.toml`` that lists those wheels and platforms (the source tree's manifest
   lists none, so that a checkout used as a local extension repository still enables);
3. runs Blender's own extension tool (``blender_ext.py``, shipped inside the ``bpy`` wheel):
   ``validate`` on the staged tree, then ``build --split-platforms`` into ``dist/``, which writes
   ``sampling_lab-<version>-<platform>.zip`` with only that platform's wheels, and ``validate``
   on every archive.

numpy is never bundled: Blender ships it, and the wheels are downloaded with ``--no-deps``.
The manifest's ``[build] paths_exclude_pattern`` keeps tests, benchmarks, docs and tools out.

Usage::

    python tools/dist.py                                   # 4 platforms x cp311, cp313
    python tools/dist.py --platforms linux-x64 --pythons cp311 --output /tmp/out
"""

from __future__ import annotations

import argparse
import importlib.util
import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parent.parent

# Blender platform -> the pip platform tag to download for. pip also accepts older tags of the
# same family (manylinux_2_17 for 2_28, macosx_10_15 for 13_0), so these are upper bounds:
# Blender 4.2+ on Linux needs glibc 2.28; embreex's macOS wheels need macOS 13.
PLATFORMS = {
    "linux-x64": "manylinux_2_28_x86_64",
    "windows-x64": "win_amd64",
    "macos-arm64": "macosx_13_0_arm64",
    "macos-x64": "macosx_13_0_x86_64",
}

# Older tags pip is also given (it does not always fall back by itself): scipy 1.14.1's Linux
# wheels are tagged manylinux_2_17 (glibc 2.17 <= 2.28, so Blender runs them).
OLDER_TAGS = {"linux-x64": ("manylinux_2_17_x86_64",)}

# Wheel Python tag -> version: Blender 4.2 to 5.0 embed Python 3.11, Blender 5.1+ Python 3.13.
PYTHONS = {"cp311": "3.11", "cp313": "3.13"}

# Modules the archive bundles (numpy comes with Blender).
BUNDLED = ("embreex", "OpenEXR", "scipy")


def log(message):
    print(f"dist: {message}", flush=True)


def pinned_requirements(path=REPO_ROOT / "requirements.txt", names=BUNDLED):
    """``name==version`` pins of ``names`` in requirements.txt.

    Returns
    -------
    dict of str -> str
        Requirement name (as :data:`BUNDLED` spells it) -> pinned version.
    """
    pins = {}
    for line in path.read_text().splitlines():
        line = line.split("#", 1)[0].strip()
        match = re.fullmatch(r"([A-Za-z0-9_.-]+)\s*==\s*([^\s;]+)", line)
        if match:
            pins[normalize(match[1])] = match[2]
    missing = [name for name in names if normalize(name) not in pins]
    if missing:
        raise SystemExit(f"dist: requirements.txt pins no version of {', '.join(missing)}")
    return {name: pins[normalize(name)] for name in names}


def normalize(name):
    """A project name as wheel file names spell it (PEP 427/503: lower case, runs -> '_')."""
    return re.sub(r"[-_.]+", "_", name).lower()


def find_wheel(folder, name, version, python):
    """The wheel of ``name==version`` for ``python`` (a tag such as ``cp311``) in ``folder``."""
    prefix = f"{normalize(name)}-{version}-{python}-"
    if not folder.is_dir():
        return None
    found = sorted(p for p in folder.glob("*.whl") if p.name.lower().startswith(prefix.lower()))
    return found[-1] if found else None


def download_wheels(pins, platforms, pythons, cache, quiet=False):
    """Every pinned wheel for every (platform, python), downloading only those not in ``cache``.

    Returns
    -------
    list of Path
        One wheel per requirement, platform and Python.
    """
    wheels = []
    for platform in platforms:
        for python in pythons:
            folder = cache / platform / python
            missing = [(n, v) for n, v in pins.items() if find_wheel(folder, n, v, python) is None]
            if missing:
                log(f"downloading {', '.join(f'{n}=={v}' for n, v in missing)} for {platform} "
                    f"{python} into {folder.relative_to(REPO_ROOT) if folder.is_relative_to(REPO_ROOT) else folder}")
                command = [sys.executable, "-m", "pip", "download", "--disable-pip-version-check",
                           "--only-binary=:all:", "--no-deps", "--platform", PLATFORMS[platform],
                           "--python-version", PYTHONS[python], "--implementation", "cp",
                           "-d", str(folder)] + [f"{n}=={v}" for n, v in missing]
                for tag in OLDER_TAGS.get(platform, ()):
                    command[command.index("--python-version"):0] = ["--platform", tag]
                if quiet:
                    command.insert(4, "--quiet")
                subprocess.run(command, check=True)
            for name, version in pins.items():
                wheel = find_wheel(folder, name, version, python)
                if wheel is None:
                    raise SystemExit(f"dist: pip downloaded no {name} {version} wheel for "
                                     f"{platform} {python} into {folder}")
                wheels.append(wheel)
    return wheels


def source_files(root=REPO_ROOT):
    """Paths (relative to ``root``) of the work tree's files that git does not ignore.

    The files git tracks and new ones it would track: the tree a checkout enabled as a local
    extension repository loads. Tracked files alone would mix edited files with missing new
    ones. The manifest's ``paths_exclude_pattern`` then decides what the archive keeps.
    """
    out = subprocess.run(["git", "-C", str(root), "ls-files", "-z", "--cached", "--others",
                          "--exclude-standard"], check=True, capture_output=True).stdout.decode()
    return sorted({Path(p) for p in out.split("\0") if p and (root / p).is_file()})


def uncommitted(root=REPO_ROOT):
    """``git status --porcelain`` lines: changes a release from this tree would include."""
    out = subprocess.run(["git", "-C", str(root), "status", "--porcelain"], check=True,
                         capture_output=True, text=True).stdout
    return [line for line in out.splitlines() if line.strip()]


def generated_manifest(source_text, platforms, wheel_paths):
    """The source manifest with ``platforms`` and ``wheels`` added before its first table.

    Top-level keys must precede the first ``[table]`` in TOML, so they go right before it.
    """
    existing = tomllib.loads(source_text)
    for key in ("platforms", "wheels"):
        if key in existing:
            raise SystemExit(f"dist: the source blender_manifest.toml already sets {key!r}; "
                             f"tools/dist.py generates it")
    lines = ["# Generated by tools/dist.py (./lab dist): the wheels bundled in the release",
             "# archives, one archive per platform (build --split-platforms).",
             "platforms = [" + ", ".join(f'"{p}"' for p in platforms) + "]",
             "wheels = ["]
    lines += [f'  "./{p.as_posix()}",' for p in wheel_paths]
    lines += ["]", ""]
    match = re.search(r"^\[", source_text, flags=re.MULTILINE)
    at = match.start() if match else len(source_text)
    text = source_text[:at] + "\n".join(lines) + "\n" + source_text[at:]
    parsed = tomllib.loads(text)
    assert parsed["platforms"] == list(platforms) and len(parsed["wheels"]) == len(wheel_paths)
    return text


def stage(stage_dir, wheels, platforms, root=REPO_ROOT):
    """Copy the source files and the wheels to ``stage_dir`` and write its manifest."""
    if stage_dir.exists():
        shutil.rmtree(stage_dir)
    stage_dir.mkdir(parents=True)
    for rel in source_files(root):
        target = stage_dir / rel
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(root / rel, target)
    wheel_dir = stage_dir / "wheels"
    wheel_dir.mkdir()
    wheel_paths = []
    for wheel in wheels:
        shutil.copy2(wheel, wheel_dir / wheel.name)
        wheel_paths.append(Path("wheels") / wheel.name)
    manifest = stage_dir / "blender_manifest.toml"
    manifest.write_text(generated_manifest(manifest.read_text(), platforms, wheel_paths))
    return manifest


def blender_ext():
    """Path of Blender's extension command line tool inside the installed ``bpy`` package."""
    spec = importlib.util.find_spec("bpy")
    if spec is None or not spec.submodule_search_locations:
        raise SystemExit("dist: the bpy package is not installed (run ./lab setup)")
    for location in spec.submodule_search_locations:
        found = sorted(Path(location).glob("*/scripts/addons_core/bl_pkg/cli/blender_ext.py"))
        if found:
            return found[-1]
    raise SystemExit("dist: bpy has no scripts/addons_core/bl_pkg/cli/blender_ext.py")


def run_ext(*args):
    """Run ``blender_ext.py`` with ``args``; its output goes to ours, a failure stops us."""
    command = [sys.executable, str(blender_ext()), *map(str, args)]
    result = subprocess.run(command, capture_output=True, text=True)
    for line in (result.stdout + result.stderr).splitlines():
        print(f"  {line}", flush=True)
    if result.returncode != 0:
        raise SystemExit(f"dist: blender_ext.py {args[0]} failed (exit {result.returncode})")
    return result.stdout


def archive_name(manifest_path, platform):
    """File name the builder gives the archive of ``platform`` (``id-version-platform.zip``)."""
    manifest = tomllib.loads(manifest_path.read_text())
    return f"{manifest['id']}-{manifest['version']}-{platform.replace('-', '_')}.zip"


def build(platforms=tuple(PLATFORMS), pythons=tuple(PYTHONS), output=REPO_ROOT / "dist",
          cache=REPO_ROOT / "build" / "wheels", stage_dir=REPO_ROOT / "build" / "stage",
          quiet=False):
    """Download, stage, validate and build; the archives' paths, one per platform.

    Returns
    -------
    dict of str -> Path
        Blender platform -> archive written to ``output``.
    """
    unknown = [p for p in platforms if p not in PLATFORMS] + [p for p in pythons if p not in PYTHONS]
    if unknown:
        raise SystemExit(f"dist: unknown platform or Python {', '.join(unknown)}; choose from "
                         f"{', '.join(PLATFORMS)} and {', '.join(PYTHONS)}")
    pins = pinned_requirements()
    changes = uncommitted()
    if changes:
        log(f"note: the work tree has {len(changes)} uncommitted change(s); the archives hold "
            f"them (a release should be built from a clean checkout):")
        for line in changes[:20]:
            print(f"  {line}", flush=True)
    wheels = download_wheels(pins, platforms, pythons, Path(cache), quiet=quiet)
    manifest = stage(Path(stage_dir), wheels, platforms)
    log(f"staged {stage_dir} with {len(wheels)} wheels; validating")
    run_ext("validate", stage_dir)
    output = Path(output)
    output.mkdir(parents=True, exist_ok=True)
    archives = {p: output / archive_name(manifest, p) for p in platforms}
    for archive in archives.values():
        archive.unlink(missing_ok=True)
    log(f"building {', '.join(platforms)} into {output}")
    run_ext("build", "--split-platforms", "--source-dir", stage_dir, "--output-dir", output)
    for platform, archive in archives.items():
        if not archive.is_file():
            raise SystemExit(f"dist: the builder wrote no {archive}")
        run_ext("validate", archive)
    for platform, archive in archives.items():
        log(f"{archive} ({archive.stat().st_size / 2**20:.1f} MiB)")
    return archives


def main(argv=None):
    parser = argparse.ArgumentParser(prog="./lab dist", description=__doc__.splitlines()[0])
    parser.add_argument("--platforms", nargs="+", default=list(PLATFORMS), metavar="PLATFORM",
                        help=f"Blender platforms (default: {' '.join(PLATFORMS)})")
    parser.add_argument("--pythons", nargs="+", default=list(PYTHONS), metavar="TAG",
                        help=f"wheel Python tags (default: {' '.join(PYTHONS)})")
    parser.add_argument("--output", default=str(REPO_ROOT / "dist"),
                        help="folder of the archives (default dist/)")
    parser.add_argument("--cache", default=str(REPO_ROOT / "build" / "wheels"),
                        help="wheel download cache (default build/wheels/)")
    parser.add_argument("--stage", default=str(REPO_ROOT / "build" / "stage"),
                        help="staging folder, emptied first (default build/stage/)")
    parser.add_argument("--quiet", action="store_true", help="no pip download output")
    args = parser.parse_args(argv)
    build(platforms=tuple(dict.fromkeys(args.platforms)), pythons=tuple(dict.fromkeys(args.pythons)),
          output=Path(args.output).resolve(), cache=Path(args.cache).resolve(),
          stage_dir=Path(args.stage).resolve(), quiet=args.quiet)
    return 0


if __name__ == "__main__":
    sys.exit(main())
