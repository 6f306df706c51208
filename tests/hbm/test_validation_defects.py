"""What the validation of HBM orbits by time integration (hbm.ti.validation, the validation
stage's log) reports, on synthetic signals and the 39-dof stand-in ROM:

- the RL-HBM force compared is the one of the RL-HBM equilibrium, sigma_k F_k(lam) (the
  residual's Lanczos filter), not the raw penalty force;
- a march returning to its orbit along a multiplier near -1 (a decaying flip transient,
  which repeats at lag 2 long before it repeats at lag 1) is not "an orbit of period 2 T";
- the log's "last deviation" is the one the verdict is judged on (the last tenth);
- displacement_error has the scale of `deviation` (half peak-to-peak), so a static offset
  of the orbit does not change it;
- force_peak is the peak of the force averaged over each recording interval T / n_time.
"""
import numpy as np
import pytest

from hbm.harmonic.fourier import FourierBasis
from hbm.harmonic.residual import build_residual
from hbm.options import CasingOptions, ContactOptions, HbmOptions
from hbm.stability.selection import DoubledBranch
from hbm.ti.validation import (SETTLED_DRIFT, OrbitValidation, _compared, compare_with_hbm, departure,
                                march_from_hbm, repeat_period)
from support import standin_rom

OMEGA, N_H = 1500.0, 8


def _validation(tau, n_periods=3, deviation=None, displacement=None, force=None, **kw) -> OrbitValidation:
    """An OrbitValidation holding the given signals (the rest zeros) on the grid tau."""
    n = len(tau)
    z = np.zeros((n, 3))
    dev = np.zeros((n_periods, 2)) if deviation is None else deviation
    growth, stays = departure(dev)
    args = dict(omega=OMEGA, subharmonic=1, n_periods=n_periods, dt=1e-7, t0=0.0, nodes=np.array([0, 1, 8]), tau=tau,
                distance=z, displacement=z if displacement is None else displacement,
                force=z if force is None else force,
                force_peak=np.zeros(3), deviation=dev, drift=np.zeros(2), growth=growth, stays=stays,
                max_penetration=0.0, contact_fraction=np.zeros(9), outcome="stays" if stays else "leaves",
                repeat=1 if stays else 0)
    args.update(kw)
    return OrbitValidation(**args)


def _rubbing_orbit(res):
    """Unknowns of a radial motion -0.1 mm + 0.6 mm cos(Omega t) of every boundary node (over the
    0.4 mm clearance: every node rubs; farthest from the casing at Omega t = pi, a phase of
    every grid of an even number of samples)."""
    xr = np.zeros((2 * N_H + 1, res.n_r))
    xr[0, 0::3] = -1e-4
    xr[1, 0::3] = 6e-4
    return res.to_unknowns(xr)


# -- 1. the RL force is the sigma-filtered one of the RL-HBM equilibrium -----------------------
def test_the_rl_force_compared_is_the_one_in_the_rl_hbm_equilibrium():
    """The harmonics of OrbitComparison.force are the nonlinear force of the residual R = (Z x -
    f + sigma F(lam)) alpha / k_ref at the compared nodes' radial dofs; the raw penalty force
    differs from it by the filter (sigma_k = sinc(k / (N_h + 1)): 0.83 at k = 3, 0.26 at 7)."""
    rom = standin_rom()
    contact = ContactOptions(mu=0.0)
    res = build_residual(rom, CasingOptions(), contact, HbmOptions(n_harmonics=N_H, n_time=64), method="rl")
    assert res.sigma[-1] < 0.5  # the filter is on
    u = _rubbing_orbit(res)
    tau = FourierBasis(N_H, 64).tau
    ti = _validation(tau)
    coeffs, lam = res.expand_harmonics(u, OMEGA), res.signals(u, OMEGA)["lam"]
    comp = compare_with_hbm(ti, coeffs, lam, "rl", sigma=res.sigma)
    # the residual's own nonlinear force: R / scale minus its linear part
    op = res.model.operator(res.fundamental(OMEGA))
    xr = res.to_coefficients(u)
    fnl = res(u, OMEGA, jacobian=False).reshape(xr.shape) * res.k_ref / res.alpha - (op.apply(xr) - op.force)
    expected = fnl[:, 3 * ti.nodes]
    assert np.abs(expected).max() > 10.0  # N: it rubs
    np.testing.assert_allclose(FourierBasis(N_H, 64).to_freq(comp.force), expected, rtol=0,
                               atol=1e-9 * np.abs(expected).max())
    assert comp.force_filter == "sigma"
    # time integration delivering exactly that force agrees to round-off; against the raw
    # penalty force it would differ by the filter's share
    agree = compare_with_hbm(_validation(tau, force=comp.force), coeffs, lam, "rl", sigma=res.sigma)
    assert agree.force_error.max() < 1e-12
    raw = compare_with_hbm(_validation(tau, force=comp.force), coeffs, lam, "rl")
    assert raw.force_filter == "none" and raw.force_error.min() > 0.05, raw.force_error
    # DLFT carries no filter (sigma = 1): its force is compared as it is
    dlft = build_residual(rom, CasingOptions(), contact, HbmOptions(n_harmonics=N_H, n_time=64), method="dlft")
    assert compare_with_hbm(ti, coeffs, lam, "dlft", sigma=dlft.sigma).force_filter == "none"


# -- 2. a decaying flip transient is not a period-2 orbit --------------------------------------
def _flip_march(q, a=0.12, n_periods=100, n_s=256):
    """(n_periods, n_s, 3) signals of an orbit plus a transient a (-q)^k along a flip mode
    (multiplier -q), and the orbit (n_s, 3)."""
    tau = 2 * np.pi * np.arange(n_s) / n_s
    orbit = np.stack([np.cos(2 * tau), np.cos(2 * tau + 0.5), 0.7 * np.cos(2 * tau + 1.0)], axis=1)
    shape = np.stack([np.cos(tau), np.sin(tau), np.cos(tau + 0.3)], axis=1)
    k = np.arange(n_periods)[:, None, None]
    return orbit[None] + a * (-q) ** k * shape[None], orbit, tau


def test_a_decaying_flip_transient_is_not_an_orbit_of_period_two():
    """Multiplier -0.99, 0.12 of the amplitude at the start: the distance to the orbit shrinks
    (0.171 -> 0.069), the last period differs from the one before by 0.127 > SETTLED_DRIFT and
    from the one two periods back by 0.0013. It stays, unsettled; it did not leave for 2 T."""
    x, orbit, tau = _flip_march(0.99)
    amp = 0.5 * np.ptp(orbit, axis=0)
    dev = (np.abs(x - orbit).max(axis=1) / amp)[:, [0, 2]]
    drift = (np.abs(x[-1] - x[-2]).max(axis=0) / amp)[[0, 2]]
    lag2 = (np.abs(x[-1] - x[-3]).max(axis=0) / amp)[[0, 2]]
    assert drift.max() > SETTLED_DRIFT and drift.max() == pytest.approx(0.127, abs=1e-3) and lag2.max() < 0.002
    growth, stays = departure(dev)
    assert stays and growth == pytest.approx(0.40, abs=0.01)
    repeat = repeat_period(x[:, :, [0, 2]], amp[[0, 2]], 10)
    assert repeat == 0
    ti = _validation(tau, n_periods=100, deviation=dev, displacement=x[-1], drift=drift, stays=stays and repeat <= 1,
                     repeat=repeat, outcome="stays")
    assert ti.verdict() == "stays, unsettled (drift 0.13)"
    # the same with a faster multiplier (-0.9): by the last tenth its lag-1 difference is
    # already within SETTLED_DRIFT, T-periodic
    x9, orbit9, _ = _flip_march(0.9, a=10.0)
    assert repeat_period(x9[:, :, [0, 2]], 0.5 * np.ptp(orbit9, axis=0)[[0, 2]], 10) == 1


def test_a_march_settling_on_a_period_two_state_is_still_one():
    """A state alternating between two shapes (0.3 of the amplitude each way) that the march
    approaches from further out (0.1 (0.97)^k more): its lag-1 difference shrinks, but to 0.6 of
    the amplitude, not to a T-periodic state: period 2, as the constant alternation is."""
    tau = np.linspace(0.0, 2 * np.pi, 64, endpoint=False)
    k = np.arange(100)[:, None, None]
    base = np.cos(tau)[None, :, None] + np.zeros((100, 1, 2))
    bump = np.sin(2 * tau)[None, :, None]
    amp = np.ones(2)
    approaching = base + (0.3 + 0.1 * 0.97 ** k) * (-1.0) ** k * bump
    d1 = np.abs(np.diff(approaching[-10:], axis=0)).max(axis=(1, 2))
    assert np.all(np.diff(d1) < 0) and d1[-1] > 0.6  # shrinking, towards 0.6
    assert repeat_period(approaching, amp, 10) == 2
    assert repeat_period(base + 0.3 * (-1.0) ** k * bump, amp, 10) == 2


# -- 3. the log's last deviation is the verdict's ----------------------------------------------
@pytest.mark.parametrize("n_periods, burst, logged", [(30, slice(20, 27), 0.2), (300, slice(270, 290), 0.9)])
def test_the_logged_last_deviation_is_the_last_tenth_the_verdict_uses(n_periods, burst, logged):
    """A burst of 0.9 of the amplitude within a 0.2 history: with 30 periods it ends before the
    last tenth (3 periods: stays, 0.200), with 300 it lies within it (30 periods: leaves,
    0.900), whatever the last 10 periods hold."""
    from types import SimpleNamespace

    from pipelines.stages.validation import TreatmentValidation, ValidationPoint, _summary

    dev = np.full((n_periods, 2), 0.2)
    dev[burst] = 0.9
    ti = _validation(np.zeros(8), n_periods=n_periods, deviation=dev)
    p = ValidationPoint("primary", "dlft", True, "chosen", "nfrc_dlft.h5", 3, OMEGA, 1, np.zeros(4), 1e-3,
                        True, "analysed", 0, 0.97, ti)
    none = ValidationPoint("isola", "dlft", False, "none")
    t = TreatmentValidation("dlft", p, none, none, DoubledBranch(False, "none"), 0.0)
    line = _summary(t, SimpleNamespace(friction_lock=None), 0.15)[0]
    assert f"last deviation {logged:.3f}" in line, line
    assert ("TI stays" in line) == (logged <= 0.6), line
    assert ti.last_deviation == pytest.approx(logged) and ti.stays == (logged <= 0.6)


# -- 4. displacement_error on the scale of deviation -------------------------------------------
def test_displacement_error_is_relative_to_the_half_peak_to_peak():
    """0.1 mm on an orbit of 1.25 mm amplitude reads 8 % (0.1 / 1.25, on the 512-point grid
    where the error's peak is sampled at 0.99998 of it) for static offsets 0, -0.5, -2 and
    +5 mm alike (it read 8.00, 5.71, 3.08 and 1.60 % divided by max |r|)."""
    n = 512
    tau = 2 * np.pi * np.arange(n) / n
    A, err = 1.25e-3, 1.0e-4  # m
    expected = err * np.abs(np.sin(6 * tau)).max() / A
    for mean in (0.0, -0.5e-3, -2e-3, 5e-3):
        hbm = np.stack([mean + A * np.cos(2 * tau)] * 3, axis=1)
        ti = _validation(tau, displacement=hbm + err * np.sin(6 * tau)[:, None])
        c = _compared(ti, "x", hbm, np.zeros((n, 3)))
        np.testing.assert_allclose(c.displacement_error, expected, rtol=1e-12)
    assert expected == pytest.approx(0.08, abs=1e-5)


@pytest.fixture(scope="module")
def standin_march():
    """The stand-in ROM marched 3 periods from a rubbing 1 Omega motion (not an orbit), DLFT
    residual, 4096 steps per period recorded on 64 and on 4096 samples."""
    rom = standin_rom()
    contact = ContactOptions(mu=0.0)
    res = build_residual(rom, CasingOptions(), contact, HbmOptions(n_harmonics=N_H, n_time=64), method="dlft")
    u = _rubbing_orbit(res)
    coeffs = res.expand_harmonics(u, OMEGA)
    dt = 2 * np.pi / (OMEGA * 4095.5)  # 4096 steps per period for both grids
    marches = {n: march_from_hbm(rom, CasingOptions(), contact.mu, coeffs, OMEGA, n_periods=3, dt=dt, n_time=n)
               for n in (64, 4096)}
    return res, u, coeffs, marches


def test_displacement_error_of_the_marched_orbit_is_its_last_deviation(standin_march):
    """The same max |r_TI - r_HBM| over the last period on the same scale: displacement_error
    against the orbit marched from is that period's deviation, at the LE and TE (the orbit's
    -0.1 mm offset does not enter: divided by max |r_HBM| = 0.7 mm it read 6/7 of it)."""
    res, u, coeffs, marches = standin_march
    ti = marches[64]
    c = compare_with_hbm(ti, coeffs, res.signals(u, OMEGA)["lam"], "the orbit")
    assert ti.deviation[-1].min() > 0.01
    np.testing.assert_allclose(c.displacement_error, ti.deviation[-1], rtol=1e-12)


# -- 5. force_peak ----------------------------------------------------------------------------
def test_force_peak_is_the_peak_of_the_force_averaged_over_each_recording_interval(standin_march):
    """One march (the same step and start) recorded on T / 4096, one step: force_peak is the
    largest single multiplier of the last period; recorded on T / 64, the largest mean over 64
    steps, at most that and here 35 times smaller at the LE (8.5 kN against 300 kN measured:
    the impacts are one-step impulses)."""
    _, _, _, marches = standin_march
    fine, coarse = marches[4096], marches[64]
    assert fine.dt == coarse.dt and fine.t0 == coarse.t0
    assert np.all(fine.force_peak > 0.0)
    # block means never exceed the largest sample they average
    assert np.all(coarse.force_peak <= fine.force_peak * (1 + 1e-12))
    # impulsive contact: the single-step peak stands well above the 64-step means
    assert fine.force_peak[0] > 10 * coarse.force_peak[0], (fine.force_peak, coarse.force_peak)
