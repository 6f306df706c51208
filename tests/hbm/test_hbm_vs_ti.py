"""Cross-method check on the rotor 67 ROM: harmonic balance against time integration.

At Omega = 1000 rad/s the blade, marched from rest for 200 revolutions, settles on a
periodic orbit of the casing's period (omega = 2 Omega) with intermittent contact. Two
independent codes must then agree on it:
- DLFT-HBM started from the time-integration orbit's harmonics converges to a solution whose
  LE amplitude equals the time-integration one;
- time marching started from that HBM solution stays on it for 100 periods.
"""
from dataclasses import replace

import numpy as np
import pytest

from hbm.harmonic.fourier import FourierBasis
from hbm.harmonic.residual import build_residual
from hbm.continuation.newton import NewtonOptions, newton_solve
from hbm.options import CasingOptions, ContactOptions, HbmOptions
from hbm.ti.sweep import steps_per_revolution
from hbm.ti.march import Recording, march, rom_modal_system
from hbm.ti.validation import (DEVIATION_TOL, GROWTH_TOL, LANDING_TOL, SETTLED_DRIFT, compare_again, compare_with_hbm,
                                confirm_orbit, departure, march_from_hbm, reached_orbit, repeat_period)
from support import coarse_rom

OMEGA, N_H, N_T = 1000.0, 40, 512


@pytest.fixture(scope="module")
def orbit():
    rom = coarse_rom()
    casing, contact = CasingOptions(), ContactOptions()
    n_per = steps_per_revolution(OMEGA, 1e-7, N_T)
    dt, n_rev = 2 * np.pi / (OMEGA * n_per), 200
    rec = Recording(start=(n_rev - 1) * n_per, stride=n_per // N_T, n_samples=N_T, dofs=np.arange(rom.n_dof),
                    force_nodes=np.arange(rom.n_boundary))
    ti = march(rom_modal_system(rom), casing, contact.mu, OMEGA, np.zeros(rom.n_dof), np.zeros(rom.n_dof), dt,
               n_rev * n_per, rec)
    res = build_residual(rom, casing, contact, HbmOptions(n_harmonics=N_H, n_time=N_T), method="dlft")
    guess = FourierBasis(N_H, N_T).to_freq(ti.displacement)[:, : 3 * rom.n_boundary]
    sol = newton_solve(res, res.to_unknowns(guess), OMEGA, NewtonOptions(tol_residual=1e-8, max_iter=30))
    return rom, casing, contact, ti, res, sol


def test_dlft_hbm_converges_to_the_time_integration_orbit(orbit):
    rom, casing, contact, ti, res, sol = orbit
    assert sol.converged, sol.reason
    r_ti = ti.displacement[:, 0]
    r_hb = FourierBasis(N_H, N_T).to_time(res.to_coefficients(sol.x)[:, 0])
    amp_ti, amp_hb = np.ptp(r_ti) / 2, np.ptp(r_hb) / 2
    assert 2e-4 < amp_ti < 2e-3  # a real rub (c = 0.4 mm, p = 0.125 mm), not a trivial orbit
    # The amplitude is a global quantity: N_h = 40 truncation and DLFT's Gibbs ripple move
    # it by well under 1 % here (0.6 % measured); 2 % leaves room for the ripple's phase.
    assert abs(amp_hb - amp_ti) / amp_ti < 0.02
    # the TI contact is exact: no penetration, multipliers >= 0
    assert ti.max_penetration < 1e-12 and ti.min_multiplier >= 0


def test_time_marching_from_the_hbm_solution_stays_on_it(orbit):
    rom, casing, contact, ti, res, sol = orbit
    coeffs = res.expand_harmonics(sol.x, OMEGA)
    ti = march_from_hbm(rom, casing, contact.mu, coeffs, OMEGA, n_periods=100, record_all=True)
    v = compare_with_hbm(ti, coeffs, res.signals(sol.x, OMEGA)["lam"], "the HBM solution")
    # 100 periods later TI is still T-periodic (it did not drift to another orbit) and as
    # close to the HBM orbit as after the first periods
    assert np.all(ti.drift < 1e-3) and ti.stays, (ti.drift, ti.growth)
    assert ti.settled and ti.verdict() == "stays" and ti.repeat == 1
    # ... and on the HBM signal: the max-norm error is the Gibbs ripple of the truncated
    # DLFT solution at the impacts (9.5 % and 9.0 % of the half peak-to-peak measured at LE
    # and TE); 12 %.
    assert np.all(v.displacement_error < 0.12), v.displacement_error
    # contact forces are impulsive in TI; compared after truncation to N_h harmonics the
    # TE force agrees to ~10 % and the LE (sharper impacts) to ~40 %: bounded, not equal.
    assert v.force_error[1] < 0.2 and v.force_error[0] < 0.6, v.force_error
    # every dof's last period on N_h harmonics: the same orbit, not another one next to it.
    # 2.0 % from the HBM orbit in the scaled unknowns (measured), and DLFT Newton started
    # there finds the orbit itself; at the three nodes the truncated signal is TI's own
    # signal but for the Gibbs ripple at the impacts (4-6 % of the amplitude measured)
    went = reached_orbit(res, ti, sol.x, OMEGA)
    assert went.distance < 0.04 and went.converged and went.solution_distance < 1e-8, went
    # the orbit and the solution found hold even harmonics of Omega only (omega = 2 Omega)
    assert went.period_ratio == went.orbit_period_ratio == 2 and went.period_words(1) == "", went
    r = FourierBasis(N_H, len(ti.tau)).to_time(ti.last_harmonics[:, 3 * ti.nodes])
    assert np.all(np.abs(r - ti.displacement).max(axis=0) < 0.1 * np.ptp(ti.displacement, axis=0))
    kept = confirm_orbit(res, ti, sol.x, OMEGA)
    assert kept.stays and kept.outcome == "stays" and kept.reached.solution_distance <= LANDING_TOL
    # the same march said to start from u = 1.3 x the orbit (not a solution): Newton from its
    # last period finds the orbit, 0.3 / 1.3 of u away, so the march went to another solution
    other = confirm_orbit(res, ti, 1.3 * sol.x, OMEGA)
    assert not other.stays and other.outcome == "another solution"
    assert other.reached.solution_distance == pytest.approx(0.3 / 1.3, rel=1e-6)
    assert other.verdict().startswith("leaves for another solution (23 %")
    # said to start from an orbit with a first harmonic as well (period one revolution), the
    # march lands on a solution of half its period, and the verdict says so
    c = res.to_coefficients(1.3 * sol.x)
    c[1, 0] = 1e-3 * np.abs(c).max()
    odd = confirm_orbit(res, ti, res.to_unknowns(c), OMEGA)
    assert (odd.reached.orbit_period_ratio, odd.reached.period_ratio) == (1, 2), odd.reached
    assert odd.verdict().startswith("leaves for another solution (23 % from the orbit, whose period is 0.5 "
                                    "revolutions where the orbit's is 1 revolution, by Newton"), odd.verdict()
    # one just past LANDING_TOL says how far, not "0 %"
    near = confirm_orbit(res, ti, 1.003 * sol.x, OMEGA)
    assert near.outcome == "another solution" and near.verdict().startswith("leaves for another solution (0.3 %")
    # started 10 % off the orbit, TI comes back (its distance shrinks: it stays) but ten
    # periods are too few for the start's transient to die out (drift 0.075 of the amplitude
    # from one period to the next, measured; 0.001 after 100 periods): the verdict says so
    late = march_from_hbm(rom, casing, contact.mu, 1.1 * coeffs, OMEGA, n_periods=10)
    assert late.stays and not late.settled and np.max(late.drift) > SETTLED_DRIFT, late.drift
    assert late.repeat == 0  # a decaying transient repeats at no lag
    assert late.verdict() == f"stays, unsettled (drift {np.max(late.drift):.2f})"
    # the orbit compared again with another march (as the stage does after a march with a
    # finer step): its signals, source and Hill verdict kept, the differences those of that march
    v = replace(v, multiplier=0.97, n_unstable=0)
    again = compare_again(late, v)
    fresh = compare_with_hbm(late, coeffs, res.signals(sol.x, OMEGA)["lam"], "the HBM solution")
    assert (again.source, again.multiplier, again.n_unstable) == (v.source, 0.97, 0)
    assert not np.allclose(again.displacement_error, v.displacement_error)
    np.testing.assert_allclose(again.displacement_error, fresh.displacement_error, rtol=1e-12)
    np.testing.assert_allclose(again.force_error, fresh.force_error, rtol=1e-12)
    # a march that kept only the three compared nodes cannot say where it went
    short = march_from_hbm(rom, casing, contact.mu, coeffs, OMEGA, n_periods=3)
    with pytest.raises(ValueError, match="record_all"):
        reached_orbit(res, short, sol.x, OMEGA)


def test_departure_from_an_orbit_is_judged_against_the_first_periods():
    """The stays rule on distance histories of the kinds measured on rotor 67 (relative to the
    orbit's amplitude, LE and TE, 100 periods)."""
    n = np.arange(100.0)[:, None]
    # a stable orbit: the start's mismatch (0.2) is reached in the first period and kept,
    # with a slowly decaying transient on top
    kept = 0.2 + 0.05 * np.exp(-n / 30.0) * np.abs(np.sin(n)) + np.zeros((1, 2))
    g, stays = departure(kept)
    assert stays and g <= 1.0
    # round-off only (an exact orbit's march): ratios of 1e-12 mean nothing
    assert departure(np.full((100, 2), 1e-12)) == (1.0, True)
    # left within ten periods for a state next to it, e.g. the other sheet near a fold (DLFT
    # isola of the default scene at 923.8 rad/s: 0.043 in the first period, 0.616 by the
    # tenth, 0.58 at the end): the first tenth holds the departure, the first three do not
    nearby = np.minimum(0.043 * np.exp(n / 3.5), 0.616) - 0.036 * (n >= 10) + np.zeros((1, 2))
    assert nearby[-10:].max() <= DEVIATION_TOL and nearby[-10:].max() <= GROWTH_TOL * nearby[:10].max()
    g, stays = departure(nearby)
    assert not stays and g == pytest.approx(0.58 / nearby[:3].max())
    # an unstable orbit left for good (log|mu| = 0.05 per period)
    assert not departure(0.2 * np.exp(0.05 * n) + np.zeros((1, 2)))[1]
    # the march drifts away at the TE only: the worse signal decides
    te = np.hstack([np.full((100, 1), 0.1), 0.1 + 0.004 * n])
    assert not departure(te)[1]
    # a short march: the baseline is its first tenth
    assert departure(np.full((20, 2), 0.3))[1]
    # never near the orbit: as far at the end as at the start (no growth), beyond DEVIATION_TOL
    assert departure(np.full((100, 2), 1.2 * DEVIATION_TOL)) == (1.0, False)
    with pytest.raises(ValueError, match="n_periods"):
        departure(np.zeros(10))


def test_the_validation_grid_holds_every_harmonic_of_the_orbit():
    """grid_size: a power of two, at least 1024, and enough samples for 2 N_h + 1 coefficients
    (the Fourier basis refuses an aliasing grid), up to N_h = 1500."""
    from hbm.harmonic.fourier import FourierBasis
    from hbm.ti.validation import grid_size

    rng = np.random.default_rng(0)
    for nh in (3, 40, 511, 600, 1500):
        n = grid_size(nh)
        assert n & (n - 1) == 0 and max(1024, 2 * nh + 2) <= n < 2 * max(1024, 2 * nh + 2)
        basis = FourierBasis(nh, n)
        c = rng.standard_normal(2 * nh + 1)
        np.testing.assert_allclose(basis.to_freq(basis.to_time(c)), c, atol=1e-12)


def test_a_march_that_repeats_every_few_periods_is_told_apart():
    """repeat_period on signals with a known period (relative to the tolerance SETTLED_DRIFT =
    0.05 of the amplitude): a T-periodic state repeats at lag 1; one that alternates between
    two shapes (a period-doubled state, as the march from the coarse rotor 67 RL primary
    orbit at 1459.5 rad/s reaches) at lag 2, not 1; period 3 at lag 3; a state quasi-periodic
    at rotation 0.216 per period (the Neimark-Sacker angle of the default scene's RL
    period-doubled orbit) at none of the lags up to MAX_REPEAT, unless its modulation is
    below the tolerance; and a longer period (5) is not claimed."""
    from hbm.ti.validation import MAX_REPEAT

    tau = np.linspace(0.0, 2 * np.pi, 64, endpoint=False)
    k = np.arange(100)[:, None, None]
    base = np.cos(tau)[None, :, None] + np.zeros((100, 1, 2))
    amp = np.ones(2)
    assert repeat_period(base, amp, 10) == 1
    bump = np.sin(2 * tau)[None, :, None]
    doubled = base + 0.3 * (-1.0) ** k * bump
    assert repeat_period(doubled, amp, 10) == 2
    assert repeat_period(base + 0.3 * np.cos(2 * np.pi * k / 3) * bump, amp, 10) == 3
    five = base + 0.3 * np.cos(2 * np.pi * k / 5) * bump
    assert MAX_REPEAT < 5 and repeat_period(five, amp, 10) == 0
    qp = base + 0.2 * np.cos(2 * np.pi * 0.216 * k) * bump
    assert repeat_period(qp, amp, 10) == 0
    assert repeat_period(base + 0.001 * np.cos(2 * np.pi * 0.216 * k) * bump, amp, 10) == 1
    # the worse signal decides: the TE alone alternates
    te = base.copy()
    te[:, :, 1] += 0.3 * (-1.0) ** k[:, :, 0] * np.sin(2 * tau)
    assert repeat_period(te, amp, 10) == 2
    # a march shorter than p + 1 periods cannot show lag p
    assert repeat_period(doubled[:2], amp, 1) == 0
