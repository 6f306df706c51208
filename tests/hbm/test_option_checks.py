"""The options dataclasses of hbm refuse a bad value where it is given, naming the option, the
value and the allowed range: hbm is used without scenes (a ROM from another FE code), and a
NaN, an infinity, a fractional count or a string flag otherwise failed far from its cause
(a non-finite residual, a singular condensation at omega = inf) or not at all (a NaN
penetration, mu or gamma, a 2.5-lobe casing, an infinite step bound: a branch computed on
a silently different model)."""
import math
import re

import numpy as np
import pytest

from hbm.continuation.arclength import ContinuationOptions
from hbm.continuation.newton import NewtonOptions
from hbm.isolas.options import IsolaOptions
from hbm.options import (CasingOptions, ContactOptions, HbmOptions, TimeIntegrationOptions, ValidationOptions,
                         check_option)
from hbm.stability.monitor import StabilityOptions

NAN, INF = math.nan, math.inf
RANGE = {"omega_min": 0.0, "omega_max": 1.0}  # ContinuationOptions' required fields

BAD = [
    (CasingOptions, {}, "n_lobes", 2.5, "n_lobes must be an integer >= 1, got 2.5"),
    (CasingOptions, {}, "n_lobes", True, "n_lobes must be an integer >= 1, got True"),
    (CasingOptions, {}, "clearance", NAN, "clearance must be a finite number >= 0 m, got nan"),
    (CasingOptions, {}, "clearance", INF, "clearance must be a finite number >= 0 m, got inf"),
    (CasingOptions, {}, "penetration", NAN, "penetration must be a finite number m, got nan"),
    (ContactOptions, {}, "epsilon", INF, "epsilon must be a finite number > 0 N/m, got inf"),
    (ContactOptions, {}, "kappa", NAN, "kappa must be a finite number > 0 N/m, got nan"),
    (ContactOptions, {}, "gamma", NAN, "gamma must be a finite number >= 0 N, got nan"),
    (ContactOptions, {}, "mu", NAN, "friction coefficient mu must be a finite number >= 0, got nan"),
    (ContactOptions, {}, "mu", -0.1, "friction coefficient mu must be >= 0, got -0.1"),
    (ContactOptions, {}, "lanczos", "false", "lanczos must be true or false, got 'false'"),
    (HbmOptions, {}, "n_harmonics", 2.5, "n_harmonics must be an integer >= 1, got 2.5"),
    (HbmOptions, {}, "n_time", 1024.0, "n_time must be an integer >= 4, got 1024.0"),
    (HbmOptions, {}, "omega_max", INF, "omega_max must be a finite number > 0 rad/s, got inf"),
    (HbmOptions, {}, "max_points", 6.5, "max_points must be an integer >= 2, got 6.5"),
    (HbmOptions, {}, "ds_max", INF, "ds_max must be a finite number > 0, got inf"),
    (HbmOptions, {}, "stability", "no", "stability must be true or false, got 'no'"),
    (HbmOptions, {}, "stability_max_gap", 0, "stability_max_gap must be >= 1 (1: every point analysed), got 0"),
    (HbmOptions, {}, "subharmonic", 1.5, "subharmonic must be an integer >= 1, got 1.5"),
    (HbmOptions, {}, "refine_bifurcations", -1, "refine_bifurcations must be >= 0 (0: no refinement), got -1"),
    (ValidationOptions, {}, "n_periods", 100.5, "n_periods must be an integer >= 3, got 100.5"),
    (ValidationOptions, {}, "dt_refinement", 0, "dt_refinement must be >= 1 (1: no second march), got 0"),
    (TimeIntegrationOptions, {}, "dt", INF, "dt must be a finite number > 0 s, got inf"),
    (TimeIntegrationOptions, {}, "n_revolutions", 200.5, "n_revolutions must be an integer >= 2, got 200.5"),
    (TimeIntegrationOptions, {}, "omega_max", INF, "omega_max must be a finite number > 0 rad/s, got inf"),
    (TimeIntegrationOptions, {}, "n_omega", 2.5, "n_omega must be an integer >= 1, got 2.5"),
    (TimeIntegrationOptions, {}, "max_order", INF, "max_order must be a finite number >= 1, got inf"),
    (TimeIntegrationOptions, {}, "stop_when_settled", "true", "stop_when_settled must be true or false"),
    (IsolaOptions, {}, "n_modes", 2.5, "n_modes must be an integer >= 0, got 2.5"),
    (IsolaOptions, {}, "harmonics", (1, NAN), "harmonics must be integers >= 1, got [1, nan]"),
    (IsolaOptions, {}, "omega_max", INF, "omega_max must be a finite number > 0 rad/s, got inf"),
    (IsolaOptions, {}, "tolerance", INF, "tolerance must be a finite number > 0, got inf"),
    (IsolaOptions, {}, "max_points", 600.5, "max_points must be an integer >= 2, got 600.5"),
    (IsolaOptions, {}, "ti_seeds", "false", "ti_seeds must be true or false, got 'false'"),
    (IsolaOptions, {}, "workers", 2.5, "workers must be an integer >= 1 (or unset), got 2.5"),
    (ContinuationOptions, RANGE, "ds_max", INF, "ds_max must be a finite number > 0, got inf"),
    (ContinuationOptions, RANGE, "max_points", 5.5, "max_points must be an integer >= 1, got 5.5"),
    (ContinuationOptions, RANGE, "x_scale", np.array([1.0, INF]), "x_scale must be finite and > 0"),
    (ContinuationOptions, RANGE, "omega_scale", INF, "omega_scale must be a finite number > 0 rad/s, got inf"),
    (ContinuationOptions, RANGE, "grow", INF, "grow must be a finite number >= 1, got inf"),
    (ContinuationOptions, RANGE, "iter_grow", 2.5, "iter_grow must be an integer >= 0, got 2.5"),
    (ContinuationOptions, RANGE, "rejoin_tol", NAN, "rejoin_tol must be a finite number > 0, got nan"),
    (ContinuationOptions, RANGE, "closed_loop_tol", -1.0, "closed_loop_tol must be > 0 (or None), got -1.0"),
    (ContinuationOptions, RANGE, "crawl_ratio", -1.0, "crawl_ratio must be > 1, got -1.0"),
    (ContinuationOptions, RANGE, "rejoin_check", None, "rejoin_check must be true or false, got None"),
    (ContinuationOptions, RANGE, "ds", 1e-7, "need 0 < ds_min <= ds <= ds_max, got 1e-06, 1e-07, "),
    (ContinuationOptions, RANGE, "ds", 1e9, "need 0 < ds_min <= ds <= ds_max, got 1e-06, 1000000000.0, "),
    (ContinuationOptions, RANGE, "direction", 0, "direction must be +1 or -1, got 0"),
    (ContinuationOptions, RANGE, "predictor", "cubic", "predictor must be 'secant' or 'quadratic', got 'cubic'"),
    (ContinuationOptions, RANGE, "max_turn_deg", 181.0, "max_turn_deg must be in (0, 180], got 181.0"),
    (ContinuationOptions, RANGE, "max_turn_deg", 0.0, "max_turn_deg must be in (0, 180], got 0.0"),
    (ContinuationOptions, RANGE, "turn_shrink_deg", 0.0, "turn_shrink_deg must be in (0, 180], got 0.0"),
    (ContinuationOptions, RANGE, "crawl_points", 0, "crawl_points must be >= 1 (or None), got 0"),
    (ContinuationOptions, RANGE, "corner_turns", 0, "corner_turns must be >= 1 (or None), got 0"),
    (NewtonOptions, {}, "max_iter", 2.5, "max_iter must be an integer >= 1, got 2.5"),
    (NewtonOptions, {}, "tol_step", INF, "tol_step must be a finite number > 0 (or None), got inf"),
    (NewtonOptions, {}, "stall_factor", NAN, "stall_factor must be a finite number in (0, 1], got nan"),
    (NewtonOptions, {}, "line_search", "yes", "line_search must be true or false, got 'yes'"),
    (StabilityOptions, {}, "n_eig", 40.5, "n_eig must be an integer >= 2, got 40.5"),
    (StabilityOptions, {}, "window", NAN, "window must be a finite number > 0, got nan"),
    (StabilityOptions, {}, "margin", -0.02, "margin must be >= 0, got -0.02"),
    (StabilityOptions, {}, "turn_tol", INF, "turn_tol must be a finite number >= 0, got inf"),
    (StabilityOptions, {}, "refine_steps", 2.5, "refine_steps must be an integer >= 0 (0: no refinement), got 2.5"),
    (StabilityOptions, {}, "refine_rtol", 0.0, "refine_rtol must be > 0, got 0.0"),
]


@pytest.mark.parametrize("cls, required, name, value, message", BAD,
                         ids=[f"{c.__name__}.{n}={v!r}" for c, _, n, v, _ in BAD])
def test_bad_option_value_is_refused_with_its_name_value_and_range(cls, required, name, value, message):
    cls(**required)  # the defaults are valid
    with pytest.raises(ValueError) as info:
        cls(**required, **{name: value})
    assert message in str(info.value)


def test_an_empty_continuation_range_is_refused():
    with pytest.raises(ValueError, match=r"^need omega_min < omega_max, got 1.0, 1.0$"):
        ContinuationOptions(1.0, 1.0)
    ContinuationOptions(1.0, 1.0 + 1e-9, max_turn_deg=180.0, turn_shrink_deg=180.0, ds=1e-6, ds_min=1e-6, ds_max=1e-6)


def test_numpy_scalars_are_accepted_as_numbers_and_counts():
    HbmOptions(n_harmonics=np.int64(4), n_time=np.int64(16), omega_max=np.float64(1500.0), stability=np.True_)
    check_option("n", np.int32(3), 1, integer=True)


@pytest.mark.parametrize("kw, msg", [
    (dict(harmonics=(1, 2, 2, 3)), r"harmonics lists 2 more than once: \[1, 2, 2, 3\]"),
    (dict(amplitudes=(1e-3, 1e-2, 1e-3)), r"amplitudes lists 0.001 more than once"),
])
def test_a_repeated_seed_value_is_refused(kw, msg):
    # accepted before: the same seeds corrected twice, the duplicates found only afterwards
    from hbm.isolas.options import IsolaOptions

    with pytest.raises(ValueError, match=msg):
        IsolaOptions(**kw)


@pytest.mark.parametrize("field, value, msg", [
    ("tolerance", float("nan"), "tolerance must be a finite number > 0, got nan"),
    ("tolerance", 0.0, "tolerance must be > 0, got 0"),
    ("refine_ratio", -0.5, "refine_ratio must be > 0, got -0.5"),
    ("workers", 2.5, "workers must be an integer >= 1"),
])
def test_the_isola_search_options_are_checked(field, value, msg):
    # unchecked before: with a NaN tolerance every "distance <= tolerance" test is false (no seed
    # on a known branch, no duplicate)
    from hbm.continuation.arclength import ContinuationOptions
    from hbm.continuation.newton import NewtonOptions
    from hbm.isolas.search import SearchOptions

    kw = dict(tolerance=1e-2, continuation=ContinuationOptions(400.0, 2000.0), newton=NewtonOptions())
    kw[field] = value
    with pytest.raises(ValueError, match=re.escape(msg)):
        SearchOptions(**kw)
