"""``python -m sampling_lab ...``: the command line of :mod:`sampling_lab.cli`."""

import os
import sys

# The renderer runs its own worker threads; BLAS threads spinning beside them only steal cores.
# This must happen before NumPy is first imported.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

from .cli import main  # noqa: E402
from .core.embree_commit import wait_abandoned  # noqa: E402

code = main()
if not wait_abandoned(0):
    # A BVH build cancelled by Ctrl-C is still stopping on Embree's threads (nothing was
    # written: no sample had been taken): exit now, without finalising Python under them.
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)
sys.exit(code)
