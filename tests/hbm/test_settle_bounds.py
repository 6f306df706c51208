"""The settle test (hbm.ti.settle) against closed-form transients.

Histories are recorded as the sweep records them (sub-sections at SUBSECTIONS per casing
period from the end of the first revolution, per-revolution radial extremes, force block
samples) from y(t) = orbit(t) + transient(t) with a transient whose size at every instant is
known in closed form:

- an offset A exp(-t / tau) decaying at exactly the decay time the test assumes: then
  |y(t) - y(t - L)| = e(t) (1 - rho_L) / rho_L for every lag L, and the module's bound
  m_L rho_L / (1 - rho_L) is exactly e(t_0), the offset at the window's first instant, for
  every lag (rho_L = exp(-L / tau));
- a decaying peak that only the per-revolution maxima see (it falls between sub-sections);
- a decaying force on one node while another node never touches the casing.
"""
import math

import numpy as np

from hbm.ti.settle import SUBSECTIONS, settle_test

OMEGA, N_L, SPR, N_KEEP, RTOL, SETTLE = 1000.0, 2, 64, 20, 1e-2, 1e-4
T_REV = 2 * math.pi / OMEGA


def history(y, f, revs, fine=512):
    """(subsections, extremes, forces) after `revs` revolutions of y(t) and f(t) ((n,) -> (n, n_ch))."""
    t_sub = T_REV + np.arange((revs - 1) * N_L * SUBSECTIONS + 1) * T_REV / (N_L * SUBSECTIONS)
    ext = []
    for b in range(revs):  # block b: (b + 1) T_rev .. (b + 2) T_rev (exclusive); the last only its start
        tt = (b + 1) * T_REV + (np.arange(fine) * T_REV / fine if b < revs - 1 else np.zeros(1))
        yy = y(tt)
        ext.append(np.stack([yy.max(axis=0), yy.min(axis=0)]))
    t_f = T_REV + np.arange((revs - 1) * SPR) * T_REV / SPR
    return y(t_sub), np.array(ext), f(t_f)


def orbit(t):
    """Two channels of period T_rev (p = 2 casing periods with two lobes)."""
    w = OMEGA * t[:, None]
    return np.cos(w + np.array([0.2, 1.3])) + 0.3 * np.sin(2 * w + np.array([0.7, 2.0]))


def no_force(t):
    return np.zeros((len(t), 2))


def window_range(ext):
    """Each channel's range over the window's n_keep + 1 extreme blocks (what 'relative to the range' means)."""
    w = ext[-(N_KEEP + 1):]
    return w[:, 0].max(axis=0) - w[:, 1].min(axis=0)


def test_an_offset_decaying_at_the_assumed_rate_is_bounded_by_its_value_at_the_window_start():
    tau = 5 * T_REV
    A = 2.0  # e(t_0) / range ~ 2e-3 at t_0 = 30 T_rev: not settled at 1e-4
    revs = 50

    def y(t):
        return orbit(t) + A * np.exp(-t / tau)[:, None]

    sub, ext, f = history(y, no_force, revs)
    v = settle_test(sub, ext, f, SPR, N_L, N_KEEP, OMEGA, tau, RTOL, 10.0, SETTLE)
    assert v.periodicity.period == 2
    # one period p T_c = T_rev: rho = exp(-T_rev / tau) = exp(-1 / 5)
    assert abs(v.decay - math.exp(-0.2)) < 1e-12
    t0 = (revs - N_KEEP) * T_REV  # the window's first sub-section instant
    expected = (A * math.exp(-t0 / tau) / window_range(ext)).max()
    assert abs(v.bound - expected) <= 1e-6 * expected
    assert expected > SETTLE and not v.settled


def test_a_decaying_peak_between_the_sub_sections_keeps_the_march_going():
    """A narrow peak (an impact) half-way between two sub-sections, decaying with tau = 20
    revolutions, raises the per-revolution maximum above the orbit's (1 at t = 0 mod T_rev)
    by up to 0.05 in the window; the sub-sections never see it. The amplitude is made of the
    extremes: the march must not stop while they still move by more than 1e-4 of the range."""
    tau = 20 * T_REV
    t_s, width = T_REV / 32, T_REV / 400
    revs = 40

    def y(t):
        phase = np.mod(t, T_REV)
        peak = 0.3 * np.exp(-t / tau) * np.exp(-0.5 * ((phase - t_s) / width) ** 2)
        return np.stack([np.cos(OMEGA * t) + peak, np.cos(OMEGA * t + 1.0)], axis=1)

    sub, ext, f = history(y, no_force, revs)
    # the excess of the window's last full-revolution maximum over the orbit's, relative to the range
    t_end = (revs - 1) * T_REV + t_s
    excess = (math.cos(OMEGA * t_s) + 0.3 * math.exp(-t_end / tau) - 1.0) / window_range(ext)[0]
    assert excess > 10 * SETTLE  # a transient the stop must not hide
    v = settle_test(sub, ext, f, SPR, N_L, N_KEEP, OMEGA, tau, RTOL, 10.0, SETTLE)
    assert v.periodicity.period == 2
    assert not v.settled and v.bound >= excess


def test_a_force_transient_on_one_node_is_seen_when_another_never_touches():
    """Node 0 presses on the casing with a force that still decays (tau = 200 revolutions, at
    10 times the tolerance of its range over the window); node 1 never touches (force 0
    throughout). Displacements exactly periodic. The force's range is the largest node's: the
    untouched node must not switch the force comparison off, and the one-period comparison
    must see the transient (e(t) rho / (1 - rho) bound ~ its value, 1e-3 of the range)."""
    tau = 200 * T_REV
    revs = N_KEEP + 2  # the first revolution the sweep asks at: one revolution of history

    def f(t):
        base = np.maximum(np.cos(OMEGA * t), 0.0)  # range 1
        return np.stack([base + 1e-3 * math.exp(revs * T_REV / tau) * np.exp(-t / tau), 0.0 * t], axis=1)

    sub, ext, fo = history(orbit, f, revs)
    v = settle_test(sub, ext, fo, SPR, N_L, N_KEEP, OMEGA, tau, RTOL, 10.0, SETTLE)
    assert v.periodicity.period == 2
    # the transient left at the window's end is 1e-3 of the force's range (1.000...): 10 times the tolerance
    assert not v.settled
    t0 = (revs - N_KEEP) * T_REV
    f_rng = np.ptp(fo[-N_KEEP * SPR:, 0])
    assert v.bound >= 0.9 * 1e-3 * math.exp((revs * T_REV - t0) / tau) / f_rng


def test_an_exact_orbit_settles_with_one_revolution_of_history():
    """The earliest call of the sweep (n_keep + 2 revolutions): a revolution-period orbit with
    nothing left of a transient settles there (bound at round-off)."""
    v = settle_test(*history(orbit, no_force, N_KEEP + 2), SPR, N_L, N_KEEP, OMEGA, 5 * T_REV, RTOL, 10.0, SETTLE)
    assert v.periodicity.period == 2 and v.settled and v.bound < 1e-9


def test_a_fifth_order_subharmonic_settles_with_lags_as_long_as_the_window():
    """nu = 5 (p = 10 casing periods, 5 revolutions a period) in the default window of 20
    revolutions after 42 revolutions: the lags 5, 10 and 20 revolutions are compared, the last
    as long as the window itself; the exact orbit settles."""
    def y(t):
        w = OMEGA * t[:, None] / 5
        return np.cos(w + np.array([0.0, 0.8])) + 0.2 * np.cos(10 * w)

    v = settle_test(*history(y, no_force, 42, fine=256), SPR, N_L, N_KEEP, OMEGA, 5 * T_REV, RTOL, 10.0, SETTLE)
    assert v.periodicity.period == 10 and v.settled and v.bound < 1e-9


def test_a_node_that_never_moves_does_not_stop_the_others_settling():
    """A third channel identically 0 (a node that never moves: range 0, nothing to compare)
    next to the exact revolution-period orbit: settled, as without it, and still not settled
    with the decaying offset of the first test on the moving channels."""
    def still(y):
        return lambda t: np.concatenate([y(t), np.zeros((len(t), 1))], axis=1)

    def force(t):
        return np.zeros((len(t), 3))

    v = settle_test(*history(still(orbit), force, N_KEEP + 2), SPR, N_L, N_KEEP, OMEGA, 5 * T_REV, RTOL, 10.0, SETTLE)
    assert v.periodicity.period == 2 and v.settled and v.bound < 1e-9
    tau = 5 * T_REV
    sub, ext, f = history(still(lambda t: orbit(t) + 2.0 * np.exp(-t / tau)[:, None]), force, 50)
    v = settle_test(sub, ext, f, SPR, N_L, N_KEEP, OMEGA, tau, RTOL, 10.0, SETTLE)
    expected = (2.0 * math.exp(-30 * T_REV / tau) / window_range(ext)[:2]).max()
    assert not v.settled and abs(v.bound - expected) <= 1e-6 * expected
