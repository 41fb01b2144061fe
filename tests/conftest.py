"""Session-wide set-up shared by tests/core and tests/addon."""

import os

# The renderer runs its own worker threads; keep BLAS single-threaded as the CLI does.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
