"""A render wakes no BLAS threads: NumPy's OpenBLAS runs a product such as ``(n, 3) @ (3,)`` on
threads of its own, which then spin on the other cores for a while after each call, taking the
cores the render's workers need (a one-thread BDPT render used 1.8 CPU seconds per wall second
while a camera-ray product went through BLAS). The command line and this test suite start with
``OPENBLAS_NUM_THREADS=1``, Blender does not: per-sample products use ``einsum`` instead
(:func:`core.textures.luminance`, :mod:`core.camera`).

The renders run in a fresh interpreter without the BLAS variables, so OpenBLAS makes its thread
pool as it does in Blender. Measured as CPU time, not wall time: the threads that existed before a
render (OpenBLAS's pool), other than the main thread, may use no more than a tenth of the render's
CPU time. Linux only (``/proc/self/task``). Detects: the product put back in BDPT's camera subpath
(``d @ axis``) gave those threads 0.40 of BDPT's 0.84 CPU seconds and 0.27 of MLT's 0.54 (MLT
walks the same camera subpaths): both fail.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import pytest

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"),
                                reason="reads thread CPU times from /proc/self/task")

CASES = {"path": 24, "light": 24, "bdpt": 4, "sppm": 4, "mlt": 8}

CHILD = textwrap.dedent("""
    import json, os, sys, threading, time
    from sampling_lab.core.integrators.bounces import uniform_limits
    from sampling_lab.core.render import RenderSettings, render
    from sampling_lab.core.scenes import cornell_box

    def thread_ticks():
        ticks = {}
        for tid in os.listdir("/proc/self/task"):
            try:
                with open(f"/proc/self/task/{tid}/stat") as f:
                    fields = f.read().rsplit(")", 1)[1].split()
            except OSError:
                continue
            ticks[int(tid)] = int(fields[11]) + int(fields[12])  # utime + stime
        return ticks

    scene = cornell_box(96, 96)
    main = threading.main_thread().native_id
    out = {}
    for name, spp in json.loads(sys.argv[1]).items():
        limits = uniform_limits(8)
        render(scene, RenderSettings(integrator=name, spp=1, threads=1, **limits))
        before, cpu = thread_ticks(), time.process_time()
        render(scene, RenderSettings(integrator=name, spp=spp, threads=1, seed=3, **limits))
        cpu = time.process_time() - cpu
        after = thread_ticks()
        others = sum(after[t] - before[t] for t in before if t != main and t in after)
        out[name] = [others / os.sysconf("SC_CLK_TCK"), cpu, len(before)]
    print(json.dumps(out))
""")


@pytest.fixture(scope="module")
def thread_cpu():
    """``{integrator: [CPU s of the pre-existing threads, CPU s of the render, threads]}``."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")}
    done = subprocess.run([sys.executable, "-c", CHILD, json.dumps(CASES)], env=env,
                          capture_output=True, text=True, timeout=300, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("integrator", list(CASES))
def test_render_keeps_blas_threads_idle(thread_cpu, integrator):
    others_s, cpu, _ = thread_cpu[integrator]
    assert cpu > 0.2, "the render is too short to judge"
    assert others_s <= 0.1 * cpu, (others_s, cpu)
