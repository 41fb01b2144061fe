"""CPU of a worker-process render's parent and children per camera sample, two trees
alternated render by render in ONE process (a measurement, not a test).

With ``workers='processes'`` the children render the units and the parent (the render loop)
unpickles each unit's output and adds it to the film; its CPU competes with the children's for
the cores. Each round renders the bench box once with each tree (the base imported a second
time as ``sampling_lab_base``, with its own worker pool) and prints, per tree, the minimum and
median over the rounds of microseconds of CPU per camera sample in the parent (all its
threads) and in the children (from ``/proc``, Linux), and the bytes of one unit's pickled
output. The head is the tree that ``sampling_lab`` resolves to::

    PYTHONPATH=/path/to/parent python tools/parent_share.py --base /tmp/base/sampling_lab \\
        --integrator bdpt --rounds 5
"""

from __future__ import annotations

import argparse
import importlib
import os
import pickle
import statistics
import time

from ab_units import BASE, HEAD, _import_base  # tools/ is the script's folder


def _child_cpu(pkg):
    """CPU seconds (user + system) of ``pkg``'s worker processes so far."""
    workers = importlib.import_module(f"{pkg}.core.workers")
    total = 0
    for child in workers.pool().children:
        with open(f"/proc/{child.proc.pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        total += int(fields[11]) + int(fields[12])
    return total / os.sysconf("SC_CLK_TCK")


def _payload_bytes(pkg, integrator, size):
    """Bytes of one pickled unit result of ``integrator`` on the bench box."""
    core = lambda name: importlib.import_module(f"{pkg}.core.{name}")  # noqa: E731
    scene = core("scenes").cornell_box(size, size, light="mesh")
    settings = core("render").RenderSettings(integrator=integrator, spp=4, threads=1, seed=0)
    integ = core("integrators").integrator_class(integrator)(
        core("prepare").prepare(scene, settings.light_selection), settings)
    sampler = core("sampling.samplers").make_sampler(settings.sampler, seed=0, spp=4,
                                                       width=size)
    pixel_filter = core("film").PixelFilter(settings.filter_type, settings.filter_width)
    window = core("worker_child").FilmWindow(0, 0, size, size)
    k = 4
    result = core("passes").render_unit(integ, sampler, window, size, pixel_filter,
                                        (0, integ.unit_paths // k, 0, k), lambda: False)
    return len(pickle.dumps(("done", 0, result), pickle.HIGHEST_PROTOCOL))


def _render(pkg, integrator, size, spp, threads):
    """(parent, children) CPU microseconds per camera sample of one render."""
    core = lambda name: importlib.import_module(f"{pkg}.core.{name}")  # noqa: E731
    scene = core("scenes").cornell_box(size, size, light="mesh")
    settings = core("render").RenderSettings(integrator=integrator, spp=spp, threads=threads,
                                             seed=0, workers="processes")
    child0 = _child_cpu(pkg)
    t0 = time.process_time()
    core("render").render(scene, settings)
    parent = time.process_time() - t0
    samples = size * size * spp
    return 1e6 * parent / samples, 1e6 * (_child_cpu(pkg) - child0) / samples


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--base", required=True, help="the base tree's package folder")
    parser.add_argument("--integrator", default="bdpt")
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--spp", type=int, default=4)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args(argv)
    _import_base(args.base)
    for pkg in (BASE, HEAD):
        print(f"{pkg}: one unit's pickled output "
              f"{_payload_bytes(pkg, args.integrator, args.size) / 1e6:.2f} MB")
        _render(pkg, args.integrator, args.size, 1, args.threads)  # start the workers, warm up
    print(f"load average at start: {os.getloadavg()}")
    times = {pkg: [] for pkg in (BASE, HEAD)}
    for _ in range(args.rounds):
        for pkg in (BASE, HEAD):
            times[pkg].append(_render(pkg, args.integrator, args.size, args.spp, args.threads))
    for pkg in (BASE, HEAD):
        parent, children = zip(*times[pkg])
        print(f"{pkg:>17}: parent min {min(parent):.3f} median {statistics.median(parent):.3f}"
              f" | children min {min(children):.3f} median {statistics.median(children):.3f}"
              f" us CPU per camera sample")
    print(f"load average at end: {os.getloadavg()}")


if __name__ == "__main__":
    main()
