"""The sweep's option checks (hbm.ti.sweep): bad speed lists are refused by name,
before any march."""
import numpy as np
import pytest

from hbm.options import CasingOptions, ContactOptions, TimeIntegrationOptions
from hbm.ti.sweep import SweepRun, sweep
from support import standin_rom

OPTS = TimeIntegrationOptions(dt=1e-6, n_revolutions=8, n_keep=2, samples_per_revolution=64)


@pytest.mark.parametrize("workers", [1, 2])
def test_an_empty_speed_list_is_refused(workers):
    with pytest.raises(ValueError, match=r"needs a list of rotation speeds, got 0 speed"):
        sweep(standin_rom(), CasingOptions(), ContactOptions(), OPTS, omegas=[], workers=workers)
    with pytest.raises(ValueError, match=r"needs a list of rotation speeds, got 0 speed"):
        SweepRun(standin_rom(), CasingOptions(), ContactOptions(), OPTS, omegas=np.array([]), workers=2)


@pytest.mark.parametrize("bad", [np.inf, np.nan, -1000.0, 0.0])
def test_a_speed_that_is_not_finite_and_positive_is_named(bad):
    with pytest.raises(ValueError, match=r"rotation speeds must be finite and > 0 rad/s, got " + f"{bad:g}"):
        sweep(standin_rom(), CasingOptions(), ContactOptions(), OPTS, omegas=[1500.0, bad], workers=1)
