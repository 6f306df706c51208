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
   when e <= settle_rtol times the range, at every instant of the window; the amplitude
   (half the range over the window) then differs from the limit cycle's by at most that.

What the bound assumes: no part of the transient decays slower than the slowest mode of
the contact-free structure. Between contacts the motion is that free motion, and contacts
(plastic impacts, friction) only dissipate; a transient kept alive by contact near a
bifurcation (a Floquet multiplier close to 1 in modulus) would violate it. Two guards: the
tolerance is far below the classifier's (1e-4 against 1e-2, so a slowly drifting orbit is
still drifting visibly at the classifier's scale long before it could pass), and the test
holds over the whole window (n_keep revolutions, n_keep n_l / p period pairs), so the
transient is seen over many periods, not one. A quasi-periodic or chaotic response never
repeats to 1e-2 over a window, so it never stops early: it runs the n_revolutions cap.
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
    bound: m rho / (1 - rho), the bound on the remaining transient / range, -; inf when
        it cannot be computed (no period, not enough history, undamped structure).
    """

    settled: bool
    periodicity: Periodicity
    mismatch: float
    decay: float
    bound: float


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
        window, (n_s, n_b), N (the force part is skipped when a period is not a whole number
        of samples).
    n_lobes: n_l. n_keep: revolutions in the window. omega: Omega, rad/s.
    decay_time: tau, s (ModalSystem.slowest_decay_time). rtol, max_order: the classifier's.
    settle_rtol: tolerance on the bound, relative to each signal's range, -.
    """
    sub = SUBSECTIONS
    n_win = n_keep * n_lobes * sub  # sub-section intervals in the window
    win_ext = extremes[-(n_keep + 1):]
    scale = win_ext[:, 0].max(axis=0) - win_ext[:, 1].min(axis=0)
    sections = subsections[-(n_win + 1)::sub]
    per = classify_period(sections, n_lobes=n_lobes, rtol=rtol, max_order=max_order, scale=scale)
    nan = float("nan")
    if per.code == PeriodClass.NONE or not math.isfinite(decay_time):
        return Settling(False, per, nan, nan, math.inf)
    lag = per.period * sub
    revs = per.period // math.gcd(per.period, n_lobes)  # whole revolutions in a multiple of p
    f_lag = per.period * samples_per_revolution // n_lobes if (per.period * samples_per_revolution) % n_lobes == 0 else 0
    n_fwin = n_keep * samples_per_revolution
    if (subsections.shape[0] < n_win + 1 + lag or extremes.shape[0] < n_keep + 1 + revs
            or forces.shape[0] < n_fwin + f_lag):
        return Settling(False, per, nan, nan, math.inf)
    t_c = 2.0 * math.pi / (n_lobes * omega)
    rho_sub = math.exp(-per.period * t_c / decay_time)
    rho_ext = math.exp(-revs * n_lobes * t_c / decay_time)
    keep = scale > 0.0
    mis_sub = mis_ext = mis_f = 0.0
    if keep.any():
        y = subsections[-(n_win + 1 + lag):, keep] / scale[keep]
        mis_sub = float(np.abs(y[lag:] - y[:-lag]).max())
        e = extremes[-(n_keep + 1 + revs):-1, :, keep] / scale[keep]  # full revolutions only
        mis_ext = float(np.abs(e[revs:] - e[:-revs]).max())
    if f_lag:
        f = forces[-(n_fwin + f_lag):]
        f_scale = float(np.ptp(f[f_lag:], axis=0).max())  # the largest node's: a grazing node's
        if f_scale > 0.0:                                # round-off forces are no transient
            mis_f = float(np.abs(f[f_lag:] - f[:-f_lag]).max()) / f_scale
    bound = max(max(mis_sub, mis_f) * rho_sub / (1.0 - rho_sub), mis_ext * rho_ext / (1.0 - rho_ext))
    return Settling(bool(bound <= settle_rtol), per, max(mis_sub, mis_ext, mis_f), rho_sub, float(bound))
