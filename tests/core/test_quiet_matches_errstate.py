"""`core.quiet.quiet` sets the same error modes as `np.errstate(kind="ignore")` and restores
them, also after an exception and in other threads."""

import itertools
import threading
import warnings

import numpy as np
import pytest

from sampling_lab.core.quiet import quiet

KINDS = ("divide", "over", "under", "invalid")


@pytest.mark.parametrize("n", range(1, 5))
def test_quiet_modes_equal_errstate_for_every_subset(n):
    for kinds in itertools.combinations(KINDS, n):
        with np.errstate(all="warn", under="raise"):  # a non-default outer state
            with np.errstate(**{k: "ignore" for k in kinds}):
                expected = np.geterr()
            outer = np.geterr()
            with quiet(*kinds):
                assert np.geterr() == expected, kinds
            assert np.geterr() == outer, kinds


def test_quiet_silences_listed_kinds_only():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with quiet("divide"):
            assert np.array([1.0]) / 0.0 == np.inf
            with pytest.raises(RuntimeWarning):
                np.array([0.0]) / 0.0  # invalid: still warns


def test_quiet_restores_after_exception():
    before = np.geterr()
    with pytest.raises(KeyError):
        with quiet("divide", "invalid", "over"):
            raise KeyError("x")
    assert np.geterr() == before


def test_quiet_in_one_thread_leaves_another_thread_loud():
    inside, seen = threading.Event(), {}

    def worker():
        inside.wait(5)
        seen["modes"] = np.geterr()

    t = threading.Thread(target=worker)
    t.start()
    with np.errstate(divide="warn"):
        with quiet("divide"):
            inside.set()
            t.join(5)
    assert seen["modes"]["divide"] == "warn"
