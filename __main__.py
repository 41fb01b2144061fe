"""``python -m sampling_lab ...``: the command line of :mod:`sampling_lab.cli`."""

import os
import sys

# The renderer runs its own worker threads; BLAS threads spinning beside them only steal cores.
# This must happen before NumPy is first imported.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

from .cli import main  # noqa: E402

sys.exit(main())
