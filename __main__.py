"""``python -m sampling_lab ...``: see :mod:`sampling_lab.addon.cli`."""

import sys

from .addon.cli import main

sys.exit(main())
