"""``bench-limits`` reads each child's own peak memory, not the one Linux carries over from the
forking process (``ru_maxrss`` is inherited across fork and exec: every child reported at
least the tool's own peak, which hid radiosity's)."""

from __future__ import annotations

import resource
import sys

import numpy as np
import pytest

from sampling_lab.tools.limits import peak_rss

PARENT_MB = 400


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="VmHWM is Linux's")
def test_peak_rss_is_the_childs_own_not_the_parents():
    grown = np.ones(PARENT_MB << 17)  # this process's high-water mark rises by PARENT_MB
    parent = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    row = peak_rss("path", (32, 24))
    del grown
    assert row["peak_source"] == "VmHWM reset before the render", row
    # A child that inherited the mark would report at least `parent` (ru_maxrss did).
    assert 0 < row["before_mb"] <= row["peak_mb"] < parent - PARENT_MB / 2, (row, parent)
