"""fem.modes.check_residuals refuses what is not a finite residual below the limit.

Its contract: a mode whose relative residual exceeds the limit, is not finite, or is NaN
(not computed) is refused, and the message names it (1-based, with its frequency). A test
written as `residual > tol` would let NaN through (every comparison with NaN is false),
so a solve that produced NaN vectors would pass the check.
"""
import numpy as np
import pytest

from fem.modes import check_residuals

F = np.array([100.0, 200.0, 300.0])


def test_finite_residuals_below_the_limit_pass():
    check_residuals(np.array([1e-9, 1e-3, 1e-2]), F, tol=1e-2)  # the limit itself is accepted


@pytest.mark.parametrize("bad, value", ((np.nan, "nan"), (np.inf, "inf"), (0.5, "0.5")))
def test_nan_inf_and_large_residuals_are_refused_by_mode(bad, value):
    with pytest.raises(RuntimeError, match=rf"mode 2 \(200 Hz\): {value}") as e:
        check_residuals(np.array([1e-9, bad, 1e-9]), F, tol=1e-2)
    assert "mode 1" not in str(e.value) and "mode 3" not in str(e.value)
