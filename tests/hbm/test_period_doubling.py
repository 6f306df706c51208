"""Period doubling: detection along a branch, branch switching to the doubled period, and
time integration (scipy's solve_ivp, independent of the HBM) on both sides.

System: m x'' + c x' + k x + lam(x) = F cos(W t) with the regularised penalty obstacle
lam(x) = kappa x / 2 + sqrt((kappa x / 2)^2 + gamma^2) at x = 0 (m = k = 1, c = 0.05,
kappa = 10, gamma = 0.1, F = 1), the project's RL-HBM with one boundary node. Coming down
from W = 4.6 its W-periodic orbit loses stability near W = 4.27 through a multiplier -1
(the bilinear oscillator's natural frequency is ~1.53, and W ~ 2.8 of it), and a
2 pi / W * 2 periodic orbit takes over.
"""
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from hbm.continuation.arclength import ContinuationOptions, continue_branch
from hbm.continuation.newton import NewtonOptions, newton_solve
from hbm.harmonic.condensation import HarmonicForcing
from hbm.harmonic.nfrc import nfrc_extras
from hbm.harmonic.residual import build_residual
from hbm.options import CasingOptions, ContactOptions, HbmOptions
from hbm.stability.bifurcation import PERIOD_DOUBLING
from hbm.stability.monitor import StabilityMonitor
from hbm.stability.switching import switch_branch

C, KAPPA, GAMMA, F = 0.05, 10.0, 0.1, 1.0
NOPT = NewtonOptions(tol_residual=1e-10, max_iter=40)


def _force(x):
    h = 0.5 * KAPPA * x
    r = np.sqrt(h * h + GAMMA ** 2)
    return h + r, 0.5 * KAPPA * (1.0 + h / r)


def _rhs(t, y, w):
    lam = _force(y[0])[0]
    return [y[1], -C * y[1] - y[0] - lam + F * np.cos(w * t)]


def _rhs_var(t, y, w):
    lam, dlam = _force(y[0])
    A = np.array([[0.0, 1.0], [-1.0 - dlam, -C]])
    return np.concatenate([_rhs(t, y[:2], w), (A @ y[2:].reshape(2, 2)).ravel()])


def _state(res, u, w, t=0.0):
    """(x, v) of the HBM orbit at time t (its basis' fundamental is w / nu)."""
    b = res.basis
    xc = res.to_coefficients(u)[:, 0]
    wf = res.fundamental(w)
    k = np.arange(1, b.n_harmonics + 1)
    a, bb = xc[1::2], xc[2::2]
    x = xc[0] + np.sum(a * np.cos(k * wf * t) + bb * np.sin(k * wf * t))
    v = np.sum(k * wf * (-a * np.sin(k * wf * t) + bb * np.cos(k * wf * t)))
    return np.array([x, v])


def _march(y0, w, n):
    """x at t = k 2 pi / w, k = 0 .. n."""
    T = 2 * np.pi / w
    return solve_ivp(_rhs, (0, n * T), y0, args=(w,), t_eval=np.arange(n + 1) * T, rtol=1e-10, atol=1e-12,
                     method="DOP853").y[0]


def _pd_multiplier(y0, w):
    """Most negative Floquet multiplier of the W-periodic orbit through shooting from y0."""
    return np.min(_multipliers(y0, w).real)


def _multipliers(y0, w):
    """Both Floquet multipliers of the W-periodic orbit through shooting from y0, (2,) complex."""
    T = 2 * np.pi / w
    y = np.array(y0, dtype=float)
    for _ in range(20):
        s = solve_ivp(_rhs_var, (0, T), np.concatenate([y, np.eye(2).ravel()]), args=(w,), rtol=1e-12, atol=1e-12,
                      method="DOP853")
        r, Phi = s.y[:2, -1] - y, s.y[2:, -1].reshape(2, 2)
        if np.linalg.norm(r) < 1e-11:
            break
        y = y - np.linalg.solve(Phi - np.eye(2), r)
    return np.linalg.eigvals(Phi)


def obstacle_residual():
    """The oscillator's RL-HBM residual (N_h = 30, N_t = 512; the obstacle a single boundary
    node at x = 0) and Newton's solution at W = 4.6, where the branches start."""
    rom = SimpleNamespace(K=np.eye(3), M=np.diag([1.0, 0.0, 0.0]), C=np.diag([C, 0.0, 0.0]), rho=np.array([0.25]),
                          theta=np.array([0.0]), rotation=1, n_boundary=1, nonlinear_dofs=np.arange(3))
    res = build_residual(rom, CasingOptions(), ContactOptions(kappa=KAPPA, gamma=GAMMA, epsilon=3.0, mu=0.0,
                                                              lanczos=False),
                         HbmOptions(n_harmonics=30, n_time=512), method="rl", forcing=HarmonicForcing(np.array([F, 0, 0]), 1),
                         alpha=1.0, distance=lambda tau: np.zeros((len(tau), 1)))
    return res, newton_solve(res, res.linear_solution(4.6), 4.6, NOPT)


def low_harmonic_branch(res30):
    """The oscillator's branch with N_h = 3 (N_t = 64), continued from W = 4.6 down to 0.3:
    (residual, branch). Its superharmonic resonances need more harmonics than 3."""
    low = replace(res30.options, n_harmonics=3, n_time=64)
    res = build_residual(res30.rom, res30.casing, res30.contact, low, method="rl", forcing=res30.forcing, alpha=1.0,
                         distance=res30._distance)
    sol = newton_solve(res, res.linear_solution(4.6), 4.6, NOPT)
    return res, continue_branch(res, sol.x, 4.6, ContinuationOptions(omega_min=0.3, omega_max=4.6, ds=0.01,
                                                                     ds_max=0.05, direction=-1, newton=NOPT,
                                                                     closed_loop_tol=None, omega_scale=1.0))


def ti_distance(res, u, w, n=100):
    """Largest distance of the n-th period of time integration (scipy's DOP853) from the
    orbit u of res (N_h = 3) at W = w, started on it, over half its peak-to-peak amplitude."""
    xr = res.to_coefficients(u)[:, 0]
    k, T = np.arange(1, 4), 2 * np.pi / w
    x_at = lambda t: xr[0] + np.sum(xr[1::2] * np.cos(k * w * t) + xr[2::2] * np.sin(k * w * t))  # noqa: E731
    ts = np.linspace((n - 1) * T, n * T, 65)
    y = solve_ivp(_rhs, (0, n * T), [x_at(0.0), np.sum(k * w * xr[2::2])], args=(w,), t_eval=ts, rtol=1e-9,
                  atol=1e-11, method="DOP853").y[0]
    ref = np.array([x_at(t) for t in ts])
    return np.abs(y - ref).max() / (0.5 * np.ptp(ref))


@pytest.fixture(scope="module")
def branch():
    res, sol = obstacle_residual()
    opts = ContinuationOptions(omega_min=4.0, omega_max=4.6, ds=0.005, ds_max=0.02, direction=-1, newton=NOPT,
                               closed_loop_tol=None, omega_scale=1.0)
    mon = StabilityMonitor.for_residual(res)
    counts = {}

    def on_point(p):
        for q, ex in mon.push(p, nfrc_extras(res, p.x)):
            counts[q.index] = ex["n_unstable"]

    br = continue_branch(res, sol.x, 4.6, opts, on_point=on_point)
    for q, ex in mon.finish():
        counts[q.index] = ex["n_unstable"]
    return res, br, mon.bifurcations, counts


def test_period_doubling_is_detected_located_and_confirmed_by_time_integration(branch):
    res, br, bifs, counts = branch
    assert br.status == "reached omega_min"
    assert [b.kind for b in bifs] == [PERIOD_DOUBLING]
    pd = bifs[0]
    assert pd.direction == 1 and pd.period_ratio == 1
    assert pd.multiplier.real < -1.0 and abs(pd.multiplier.imag) < 1e-6 * abs(pd.multiplier)
    assert [counts[i] for i in sorted(counts)] == sorted(counts[i] for i in counts)  # 0 ... 0 1 ... 1
    # where shooting's multiplier is exactly -1: the located Omega interpolates log|mu|
    # linearly between the bracketing points (0.02 apart), so it must lie within the
    # bracket of the exact one (measured 4e-4 off)
    lo, hi = sorted(pd.omega_bracket)
    y_lo, y_hi = _state(res, br.x[pd.index + 1], br.omega[pd.index + 1]), _state(res, br.x[pd.index], br.omega[pd.index])
    w_exact = brentq(lambda w: _pd_multiplier(y_lo if w < 0.5 * (lo + hi) else y_hi, w) + 1.0, lo, hi, xtol=1e-8)
    assert lo <= pd.omega <= hi
    assert abs(pd.omega - w_exact) < hi - lo
    # time integration: above the period doubling the W-periodic orbit is kept for 300
    # periods (HBM's N_h = 30 orbit is off the exact one by ~1e-9 and the perturbation
    # decays); below it the orbit is left for a 2-periodic one (x(kT) alternates)
    i_above = int(np.argmin(np.abs(br.omega - (hi + 0.08))))
    x = _march(_state(res, br.x[i_above], br.omega[i_above]), br.omega[i_above], 300)
    assert np.abs(x[-20:] - x[0]).max() < 1e-6
    # (0.25 below it, where the new orbit is ~1e-2 away, 7e-3 and 1e-2 at x(kT), and
    # attracts within tens of periods: nearer, its multiplier is close to 1 and 300 periods
    # do not settle it to 1e-5)
    i_below = int(np.argmin(np.abs(br.omega - (lo - 0.25))))
    x = _march(_state(res, br.x[i_below], br.omega[i_below]), br.omega[i_below], 300)
    assert np.abs(x[-20:] - x[0]).max() > 5e-3  # left the W-periodic orbit ...
    assert np.abs(x[-20:] - x[-22:-2]).max() < 1e-5  # ... for a 2-periodic one
    assert np.abs(x[-20:] - x[-21:-1]).min() > 1e-3


def test_switched_branch_is_period_doubled_and_time_integration_stays_on_it(branch):
    res, br, bifs, _ = branch
    pd = bifs[0]
    i = pd.index + 1  # the point past the bifurcation
    st = switch_branch(res, br.x[i], br.omega[i], pd)
    assert st.newton.converged, st.newton.reason
    assert st.residual.nu == 2 and st.residual.basis.n_harmonics == 61
    # the new orbits carry the odd harmonics of W / 2, absent from the old one: 13 % of
    # the start point's harmonics (2-norm) already, growing away from the bifurcation
    assert st.odd_content > 0.05
    opts = ContinuationOptions(omega_min=3.4, omega_max=4.6, ds=0.005, ds_max=0.02, direction=-1, newton=NOPT,
                               closed_loop_tol=None, omega_scale=1.0, max_points=300)
    b2 = continue_branch(st.residual, st.u, st.omega, opts)
    assert b2.status == "reached omega_min"
    xr = st.residual.to_coefficients(b2.x[-1])
    odd = np.linalg.norm(xr[np.concatenate([[False], np.repeat(np.arange(1, 62) % 2 == 1, 2)])])
    assert odd > 0.1 * np.linalg.norm(xr)
    # time integration from the period-doubled HBM orbit at the end of the branch stays on
    # it for 200 periods 2 pi / W: x(kT) alternates between the HBM orbit's x(0), x(T)
    # (N_h = 61 of W / 2: the orbit within ~1e-8 of the exact one; 1e-6)
    w = b2.omega[-1]
    y0 = _state(st.residual, b2.x[-1], w)
    x = _march(y0, w, 200)
    x_T = _state(st.residual, b2.x[-1], w, t=2 * np.pi / w)[0]
    assert abs(x_T - y0[0]) > 1e-2
    assert np.abs(x[0::2] - y0[0]).max() < 1e-6
    assert np.abs(x[1::2] - x_T).max() < 1e-6


def test_a_branch_computed_without_stability_gets_it_afterwards(branch):
    """What the isola search does with the branches it continues (hbm.isolas.harmonic.describe):
    the monitor replayed over stored points, here a branch sampled at other arc lengths than
    the fixture's. The reference is shooting's multiplier -1, not the fixture's monitor."""
    from hbm.isolas.harmonic import describe
    from hbm.stability.monitor import StabilityOptions

    res = branch[0]
    sol = newton_solve(res, res.linear_solution(4.6), 4.6, NOPT)
    opts = ContinuationOptions(omega_min=4.0, omega_max=4.6, ds=0.003, ds_max=0.012, direction=-1, newton=NOPT,
                               closed_loop_tol=None, omega_scale=1.0)
    br = continue_branch(res, sol.x, 4.6, opts)
    ok = br.converged
    d = describe(res, True, (1.0, 1.0), StabilityOptions(max_gap=8))(br.omega[ok], br.x[ok])
    t = d["tables"]["bifurcations"]
    assert list(t["kind"][0]) == [PERIOD_DOUBLING]
    (i,), (w_pd,) = t["index"][0], t["omega"][0]
    om = br.omega[ok]
    lo, hi = sorted((om[i], om[i + 1]))
    y = _state(res, br.x[ok][i], om[i])
    w_exact = brentq(lambda w: _pd_multiplier(y, w) + 1.0, lo - 0.01, hi + 0.01, xtol=1e-8)
    assert abs(w_pd - w_exact) < hi - lo
    # every point's flag on the right side of shooting's crossing; 13 of the 54 analysed
    assert np.array_equal(d["stable"], om > w_exact)
    assert np.array_equal(d["n_unstable"], (om < w_exact).astype(int))
    assert d["stability_analysed"].sum() < 0.35 * len(om), (d["stability_analysed"].sum(), len(om))
    assert np.all(np.isfinite(d["leading_multipliers"][d["stability_analysed"], 0]))


def test_a_doubled_branch_through_the_period_doubling_is_traced_to_it(branch):
    """hbm.isolas.harmonic.doubling_origin: the switched branch continued back through the
    period doubling passes through an orbit without W / 2 content, which lies on the
    W-periodic branch, at the located doubling's Omega (within 0.05, the branch's step
    ds_max is 0.02); its part below 4.45 rad/s against only the W-periodic branch's part
    above 4.5 rad/s, far from the doubling, is traced to nothing."""
    from hbm.continuation.arclength import ContinuationOptions as CO
    from hbm.isolas.harmonic import DOUBLING_SHARE, doubling_origin, new_share
    from hbm.isolas.membership import KnownBranch
    from hbm.isolas.search import SearchOptions

    res, br, bifs, _ = branch
    pd = bifs[0]
    i = pd.index + 1
    st = switch_branch(res, br.x[i], br.omega[i], pd)
    opts = CO(omega_min=3.9, omega_max=4.6, ds=0.005, ds_max=0.02, direction=1, newton=NOPT, closed_loop_tol=None,
              omega_scale=1.0, max_points=60)
    b2 = continue_branch(st.residual, st.u, st.omega, opts)
    harmonics = np.array([nfrc_extras(st.residual, x)["harmonics"] for x in b2.x])
    doubled = SimpleNamespace(x=b2.x, omega=b2.omega, converged=b2.converged, extras={"harmonics": harmonics})
    assert new_share(harmonics[b2.converged]).min() < DOUBLING_SHARE
    known = [KnownBranch.of(br.omega, br.x, "W-periodic", br.converged)]
    search = SearchOptions(tolerance=1e-2, continuation=opts, newton=NOPT)
    hit = doubling_origin(res, st.residual, None, doubled, known, search)
    assert hit is not None and hit[0] == 0 and abs(hit[1] - pd.omega) < 0.05
    above = br.omega > 4.5
    far = [KnownBranch.of(br.omega[above], br.x[above], "W-periodic above 4.5", br.converged[above])]
    cut = b2.omega < 4.45
    part = SimpleNamespace(x=b2.x[cut], omega=b2.omega[cut], converged=b2.converged[cut],
                           extras={"harmonics": harmonics[cut]})
    assert doubling_origin(res, st.residual, None, part, far, search) is None
    assert doubling_origin(res, st.residual, None, part, known, search)[0] == 0
