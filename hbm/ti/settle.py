"""When a march from rest has provably settled on a periodic steady state (the sweep's early stop).

A transient of a damped structure dies out but never vanishes: "settled" has to mean that
what is left cannot change the reported numbers by more than a stated tolerance. The rule:

1. The periodicity classifier (hbm.ti.periodicity, its own tolerance) finds a period of p
   casing periods T_c in the window of the last n_keep revolutions: the candidate orbit.
2. The response is compared with itself one period earlier, y(t) - y(t - p T_c), over the
   whole window: every contact node's radial displacement at SUBSECTIONS instants per casing
   period (not only at the Poincare sections, so that a transient cannot hide at the
   sampling phase), its per-revolution maximum and minimum (what the amplitude is made of),
   and its normal contact force at the output rate (block means; a node held on the casing
   hides an interior transient from its displacement, not from its force): m = the largest
   difference relative to the range in the window (each node's for displacements, the
   largest node's for forces).
3. The window's remaining transient is bounded by e <= m rho / (1 - rho), rho = exp(-p T_c / tau)
   with tau the slowest free-decay time of the structure (1 / min xi_k w_k for modal damping:
   0.36 s for rotor 67's 1B at xi = 1e-3, i.e. ~60 revolutions at 1000 rad/s). Why: a
   transient that decays by a factor rho (or faster) per period, e(t) = rho e(t - T), gives
   |y(t) - y(t - T)| = |e(t) - e(t - T)| >= (1 - rho) |e(t - T)| >= e(t) (1 - rho) / rho, for
   any phase of the decaying oscillation (|rho' e^{i phi} - 1| >= 1 - |rho'|). The march stops
   when e <= settle_rtol times the range at the compared instants of the window; the
   amplitude (half the range over the window) then differs from the limit cycle's by at most
   that. Between those instants a transient decaying at exactly rho can exceed the tolerance
   by about a tenth (1.106e-4 against 1e-4 in 600 random trials at 2.75 Omega; the amplitude
   error stayed within 0.71 of the tolerance), which no safety factor is spent on.
4. The same argument holds with the response compared with itself L whole revolutions
   earlier (L a multiple of the period): m_L rho^L / (1 - rho^L), rho per revolution. Each
   lag gives a valid bound, so the smallest is taken, over L = one period and L = 1, 2, 4,
   8, ... times the revolutions of a period, as far back as the march goes. Why: a march on
   a time grid does not repeat exactly even on its limit cycle (contact starts and ends on
   steps, which fall at other phases from one period to the next), so m has a floor (1e-6
   to 1e-4 of the range on rotor 67 at dt = 1e-7) that does not decay. Over one period the
   factor rho / (1 - rho) is 50 to 120 on rotor 67 and multiplies that floor above the
   tolerance for ever; over 20 revolutions it is about 1. A transient shows over a long lag
   as much as over a short one (m_L grows as 1 - rho^L), so nothing is traded for it.

5. A part of the response that does not decay (a weak quasi-periodic component, which the
   classifier's 1e-2 lets through) breaks the assumption of rule 3, and a long lag of rule 4
   can straddle it by chance (a lag that is nearly a whole number of its cycles). Whatever
   the model, two instants of the window one lag apart differ by at most twice the window's
   distance from an orbit of that period, so half of that difference (every lag shorter than
   the window, both instants in it) is a lower bound on what is left; the bound is at least
   that. A decaying transient within the bound differs by at most twice the bound between
   two instants of the window (plus the time grid's floor of rule 4, far below the
   tolerance), so this does not delay a stop the rules above allow.

What the bound assumes: no part of the transient decays slower than the slowest mode of
the contact-free structure. Between contacts the motion is that free motion, and contacts
(plastic impacts, friction) only dissipate; a transient kept alive by contact near a
bifurcation (a Floquet multiplier close to 1 in modulus) would violate it, and the long
lags of rule 4 then underestimate it more than one period does (by rho^L). Two guards: the
tolerance is ten times below the classifier's (1e-3 by default against 1e-2, so a slowly
drifting orbit is still drifting visibly at the classifier's scale long before it could
pass), and the test holds over the whole window (n_keep revolutions, n_keep n_l / p period
pairs), so the transient is seen over many periods, not one. On the default rotor 67 sweep
every speed stopped early has its class and LE amplitude (to 3e-4) of 200 revolutions
(benchmarks/bench_ti.py --full-sweep --compare-full). A quasi-periodic or chaotic response
does not repeat to 1e-2 over a window (no period), nor, when its non-periodic part is weaker,
to 2 settle_rtol (rule 5), so it never stops early: it runs the n_revolutions cap, with two
exceptions that no window can tell from a settled orbit. A persistent part of amplitude a
(relative to the range) whose phase slips by only eps cycles a revolution against the orbit (a
slow beat) changes by 2 a sin(pi eps L) over a lag of L revolutions, as a transient at the
assumed decay would: it stops the march once that times rho^L / (1 - rho^L) is below the
tolerance at one lag and its change within the window is below twice the tolerance (a = 5e-3,
eps = 2e-3, tau = 60 revolutions, settle_rtol = 1e-3: stopped at 149 revolutions through
L = 128, class right, amplitude 2.9e-3 of the range from the one at 200 revolutions; over the
beat it moves by 2 a). A part that grows (an orbit that loses stability, e.g. a period
doubling growing from 1e-7 of the range) is invisible until it is large: the march stops on
the orbit it is leaving. A march with a value that is not finite anywhere in its history has
blown up: no period, never settled.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hbm.ti.periodicity import PeriodClass, Periodicity, classify_period

#: Instants per casing period at which the settle test compares the response with itself.
SUBSECTIONS = 8


@dataclass(frozen=True)
class Settling:
    """Verdict of the settle test on one window.

    settled: whether the window's remaining transient is within the tolerance.
    periodicity: the classifier's verdict on the window's Poincare sections.
    mismatch: max |y(t) - y(t - p T_c)| / range over the window (sub-sections,
        per-revolution extremes and contact forces of every node), -; nan without a period
        or history.
    decay: rho, the slowest free decay over one period p T_c, -.
    bound: the smallest m_L rho^L / (1 - rho^L) over the lags L (rule 4), at least half the
        window's own non-repeat (rule 5), the bound on the remaining transient / range, -;
        inf when it cannot be computed (no period, not enough history, undamped structure).
    lag: the lag that gave the bound, in casing periods (0 when bound is inf).
    """

    settled: bool
    periodicity: Periodicity
    mismatch: float
    decay: float
    bound: float
    lag: int = 0


def settle_test(subsections: np.ndarray, extremes: np.ndarray, forces: np.ndarray, samples_per_revolution: int,
                n_lobes: int, n_keep: int, omega: float, decay_time: float, rtol: float, max_order: float,
                settle_rtol: float) -> Settling:
    """Apply the rule of the module docstring to the end of a march.

    subsections: radial displacement of the n_b nodes at SUBSECTIONS instants per casing
        period, the last one at the end of the window, (n_sub, n_b), m; n_sub may exceed
        the window (history for the lag).
    extremes: per-revolution radial max and min of every node, the last revolution being
        the last full one of the window, then the lone final step, (n_rev + 1, 2, n_b), m.
    forces: normal contact force of every node, block means at samples_per_revolution per
        revolution, the last one complete and half a sample interval before the end of the
        window, (n_s, n_b), N (when a period is not a whole number of samples, the forces are
        compared over the whole revolutions of a multiple of the period instead).
    n_lobes: n_l. n_keep: revolutions in the window. omega: Omega, rad/s.
    decay_time: tau, s (ModalSystem.slowest_decay_time). rtol, max_order: the classifier's.
    settle_rtol: tolerance on the bound, relative to each signal's range, -.
    A value that is not finite in any of the three arrays (history included) gives no period
    (NONE, mismatch nan) and no stop, whatever the Poincare sections say.
    """
    nan = float("nan")
    if not all(np.isfinite(a).all() for a in (subsections, extremes, forces)):  # a march that blew up
        return Settling(False, Periodicity(PeriodClass.NONE, 0, nan, nan), nan, nan, math.inf)
    sub = SUBSECTIONS
    n_win = n_keep * n_lobes * sub  # sub-section intervals in the window
    win_ext = extremes[-(n_keep + 1):]
    scale = win_ext[:, 0].max(axis=0) - win_ext[:, 1].min(axis=0)
    sections = subsections[-(n_win + 1)::sub]
    per = classify_period(sections, n_lobes=n_lobes, rtol=rtol, max_order=max_order, scale=scale)
    if per.code == PeriodClass.NONE or not math.isfinite(decay_time):
        return Settling(False, per, nan, nan, math.inf)
    t_c = 2.0 * math.pi / (n_lobes * omega)
    keep = scale > 0.0
    n_fwin = n_keep * samples_per_revolution
    # the largest node's force range: a grazing node's round-off forces are no transient
    f_scale = float(np.ptp(forces[-n_fwin:], axis=0).max()) if forces.shape[0] >= n_fwin > 0 else 0.0
    y = subsections[:, keep] / scale[keep]
    e = extremes[:-1, :, keep] / scale[keep]  # full revolutions only (the last is the lone final step)

    own = [0.0]  # rule 5: half the largest difference of two instants both in the window

    def largest(d: np.ndarray, lag: int, n: int, unit: float = 1.0) -> float:
        """max of d / unit (rows of d: the window's n + 1 or n instants, each against the one
        lag earlier), its rows whose earlier instant lies in the window too counted into own."""
        if lag < n:
            inner = float(d[lag:].max()) / unit
            own[0] = max(own[0], 0.5 * inner)
            return max(inner, float(d[:lag].max()) / unit)
        return float(d.max()) / unit

    def mismatch(lag_sub: int, lag_rev: int, lag_f: int) -> float | None:
        """Largest difference between the window and itself lag_sub sub-sections (lag_rev
        revolutions of extremes, lag_f force samples; 0: not compared) earlier, relative to
        the range; None without enough history."""
        if (y.shape[0] < n_win + 1 + lag_sub or e.shape[0] < n_keep + lag_rev
                or (lag_f and forces.shape[0] < n_fwin + lag_f)):
            return None
        m = 0.0
        if lag_sub and keep.any():
            m = largest(np.abs(y[-(n_win + 1):] - y[-(n_win + 1 + lag_sub):-lag_sub]), lag_sub, n_win)
        if lag_rev and keep.any():
            ee = e[-(n_keep + lag_rev):]
            m = max(m, largest(np.abs(ee[lag_rev:] - ee[:-lag_rev]), lag_rev, n_keep))
        if lag_f and f_scale > 0.0:
            ff = forces[-(n_fwin + lag_f):]
            m = max(m, largest(np.abs(ff[lag_f:] - ff[:-lag_f]), lag_f, n_fwin, f_scale))
        return m

    # rule 3, one period: sub-sections and forces over p T_c, extremes over the whole
    # revolutions of a multiple of p
    revs = per.period // math.gcd(per.period, n_lobes)
    whole = (per.period * samples_per_revolution) % n_lobes == 0  # a period is whole force samples
    lag_f = per.period * samples_per_revolution // n_lobes if whole else 0
    m_sub = mismatch(per.period * sub, 0, lag_f)
    # forces whose period is not whole samples (n_l = 3 lobes at 256 samples a revolution):
    # compared over the revs whole revolutions of the extremes instead, never skipped
    m_ext = mismatch(0, revs, 0 if whole else revs * samples_per_revolution) if m_sub is not None else None
    if m_sub is None or m_ext is None:
        return Settling(False, per, nan, nan, math.inf)
    rho_sub = math.exp(-per.period * t_c / decay_time)
    rho_ext = math.exp(-revs * n_lobes * t_c / decay_time)
    bound = max(m_sub * rho_sub / (1.0 - rho_sub), m_ext * rho_ext / (1.0 - rho_ext))
    lag = per.period
    # rule 4: whole revolutions, multiples of revs, as far back as the march goes
    lag_rev = revs
    while True:
        m = mismatch(lag_rev * n_lobes * sub, lag_rev, lag_rev * samples_per_revolution)
        if m is None:
            break
        rho = math.exp(-lag_rev * n_lobes * t_c / decay_time)
        b = m * rho / (1.0 - rho)
        if b < bound:
            bound, lag = b, lag_rev * n_lobes
        lag_rev *= 2
    # rule 5: the window's own non-repeat, both instants inside it (a persistent
    # quasi-periodic part the long lags of rule 4 may straddle by chance)
    bound = max(bound, own[0])
    return Settling(bool(bound <= settle_rtol), per, max(m_sub, m_ext), rho_sub, float(bound), lag)
