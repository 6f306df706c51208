"""Periodicity of a steady response from its Poincare sections (Fig. 5 of the reference paper).

The casing has n_l lobes, so the forcing has period T_c = 2 pi / (n_l Omega). The response is
sampled once per casing period (a Poincare section at t = k T_c) and its period is the
smallest number p of casing periods after which every section repeats, within a tolerance
relative to the signal's range. Then omega = n_l Omega / p, and the order nu = Omega / omega.
For the paper's two lobes: p = 1 is omega = 2 Omega, p = 2 is omega = Omega, p > 2 is
subharmonic (nu = p / 2), and no repeat up to nu = max_order is "no periodicity".
"""
from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np


class PeriodClass(enum.IntEnum):
    """Periodicity class of a steady response (the markers of Fig. 5).

    An IntEnum: the integer codes are what artifacts store (SweepResult.period_class).
    """

    CASING = 0         # omega = n_l Omega, the casing's own period (2 Omega for two lobes)
    REVOLUTION = 1     # omega = Omega
    SUBHARMONIC = 2    # omega < Omega, omega = Omega / nu
    NONE = 3           # no period with nu <= max_order (quasi-periodic, chaotic, omega < Omega / max_order)
    SUPERHARMONIC = 4  # Omega < omega < n_l Omega (reachable only with n_l > 2 lobes, e.g. p = 2 of 3)

    def label(self, n_lobes: int = 2, max_order: float = 10.0) -> str:
        """Plain-text name, e.g. 'omega = 2 Omega' for CASING with two lobes."""
        return {PeriodClass.CASING: f"omega = {n_lobes} Omega" if n_lobes > 1 else "omega = Omega",
                PeriodClass.REVOLUTION: "omega = Omega",
                PeriodClass.SUBHARMONIC: "subharmonic (omega < Omega)",
                PeriodClass.NONE: f"no periodicity or omega < Omega / {max_order:g}",
                PeriodClass.SUPERHARMONIC: f"Omega < omega < {n_lobes} Omega"}[self]


@dataclass(frozen=True)
class Periodicity:
    """Classification of one signal.

    code: the PeriodClass.
    period: p, the period in casing periods (0 when NONE). order: nu = Omega / omega = p / n_l,
    - (nan when NONE). mismatch: max |y_{k+p} - y_k| / range for the accepted p, or the
    smallest one over all tried p when NONE (below rtol when only a multiple of failed
    periods repeated, see classify_period), -.
    """

    code: PeriodClass
    period: int
    order: float
    mismatch: float


#: How many times better than each of its failed divisors q a multiple p of them must repeat
#: (mismatch_p <= mismatch_q / MULTIPLE_MARGIN) to be accepted. Why 2: under uniform noise of
#: any level, the best multiple of the true period q reaches 0.55 of mismatch_q or more in 99 %
#: of draws of 41 sections on one channel (0.75 on two or three; below 1 / 2 in 0.15 %), the
#: max over fewer pairs of the same noise; while an orbit of period p whose part that does not
#: repeat at q has amplitude c, under pair noise N, has mismatch_q up to 2 c + N and mismatch_p
#: up to N: 2 accepts it whenever c >= N / 2.
MULTIPLE_MARGIN = 2.0

#: Without a scale, a channel's range is raised to this fraction of its largest |value|: the
#: sections of a response with the casing's period (p = 1) all hold one value, so their own
#: range is round-off (1.7e-18 m on 41 sections of 1e-4 (0.3 + cos 2 Omega t) m, 1e-14 of
#: their size), which, taken as the range, reads as a mismatch of order 1 (0.39) and the class
#: NONE. 1e-9 puts such round-off 1e-5 of the floor, far within rtol, while a change of the
#: sections by 1e-9 rtol of their size (1e-11 at rtol = 1e-2) still counts.
ROUNDOFF_FLOOR = 1e-9


def classify_period(sections: np.ndarray, n_lobes: int = 2, rtol: float = 1e-2, max_order: float = 10.0,
                    scale: np.ndarray | None = None) -> Periodicity:
    """Smallest period of a sequence of Poincare sections, in casing periods.

    sections: samples y_k at t_k = t_0 + k T_c, (n_sec,) or (n_sec, n_channels), any unit;
    each channel is scaled by `scale` (n_channels,), same unit: the signal's range over the
    whole window, which the sections alone may not see (hbm.ti.settle passes it); default: the
    range of the sections, raised to ROUNDOFF_FLOOR times the channel's largest |y| (so that a
    response of the casing's period, whose sections differ by round-off only, is p = 1).
    Channels of zero scale are ignored.
    n_lobes: n_l, casing periods per revolution. rtol: accepted mismatch relative to the
    range, -. max_order: largest nu = Omega / omega still called subharmonic, -.
    A period p is accepted when every section of the window repeats after p casing periods:
    max_k max_ch |y_{k+p} - y_k| / range_ch <= rtol over k = 0 .. n_sec - 1 - p (a multiple of
    periods that failed: see MULTIPLE_MARGIN below), and only p <= (n_sec - 1) / 2 are tried so
    that each accepted period is seen at least twice.
    A signal of zero range (constant) has period 1; one with a value (or a scale) that is not
    finite has none (NONE, mismatch nan).

    What the tolerance lets through, by design: the smallest p within rtol wins, so an orbit of
    period 4 whose sections repeat after 2 within rtol (a period doubling weaker than rtol) is
    p = 2; a drift (unfinished transient) of at most rtol per period, and a quasi-periodic part
    whose near-repeat after some p is within rtol, are periodic with that p. Larger p are judged
    on fewer pairs (n_sec - p): a non-repeat just above rtol at the true period q (noise) can
    fall below it at a multiple p of q by chance (a p = 2 orbit with pair noise of 1.3 rtol on
    41 sections passes at p = 8, 18 or 20, depending on the draw). So a multiple p of periods q
    that failed is accepted only when it repeats MULTIPLE_MARGIN times better than each of them
    (mismatch_p <= mismatch_q / 2), i.e. when what repeats at p and not at q stands out of the
    non-repeat; such a signal is NONE. A quasi-periodic part still passes where its near-repeat
    beats the failed divisors by that margin: a part of amplitude 1 % of the range at sqrt(2)
    Omega on a p = 2 orbit is p = 10 (5 sqrt(2) = 7.07 cycles). NONE also covers a window too
    short to see a period twice: nu > (n_sec - 1) / (2 n_l), below max_order when n_sec
    < 2 max_order n_l + 1. Each channel is held to rtol of its own scale: without `scale`, a
    channel whose sections barely move (above the round-off floor) breaks the period of all,
    and one whose sections sit at 0 (a zero crossing at every section) is judged on its
    round-off; pass the signal's range (or a common scale) to avoid both.
    Raises ValueError for n_lobes < 1, an rtol that is negative or not finite, a max_order
    that is not finite or below 1 / n_lobes (p = 1 could not be tried) and a negative scale.
    """
    _check_arguments(n_lobes, rtol, max_order, scale)
    y = np.asarray(sections, dtype=float)
    if y.ndim == 1:
        y = y[:, None]
    n_sec = y.shape[0]
    if n_sec < 3:
        raise ValueError(f"need at least 3 Poincare sections, got {n_sec}")
    if not np.isfinite(y).all():  # a march that blew up repeats nothing
        return Periodicity(code=PeriodClass.NONE, period=0, order=float("nan"), mismatch=float("nan"))
    rng = _own_range(y) if scale is None else np.broadcast_to(np.asarray(scale, float), y.shape[1:])
    if not np.isfinite(rng).all():
        return Periodicity(code=PeriodClass.NONE, period=0, order=float("nan"), mismatch=float("nan"))
    keep = rng > 0.0
    if not keep.any():
        return Periodicity(code=PeriodClass.CASING, period=1, order=1.0 / n_lobes, mismatch=0.0)
    y = y[:, keep] / rng[keep]
    p_max = min(int(np.floor(max_order * n_lobes + 1e-9)), (n_sec - 1) // 2)
    mis = np.full(p_max + 1, np.inf)  # mis[p]: max |y_{k+p} - y_k| / range, -
    for p in range(1, p_max + 1):
        mis[p] = float(np.abs(y[p:] - y[:-p]).max())
        if mis[p] <= rtol and mis[p] <= _failed_divisors(mis, p) / MULTIPLE_MARGIN:
            return Periodicity(code=_code(p, n_lobes), period=p, order=p / n_lobes, mismatch=float(mis[p]))
    return Periodicity(code=PeriodClass.NONE, period=0, order=float("nan"), mismatch=float(mis[1:].min()))


def _own_range(y: np.ndarray) -> np.ndarray:
    """Range of each channel of the sections y, (n_sec, n_ch) -> (n_ch,), y's unit, raised to
    ROUNDOFF_FLOOR times the channel's largest |y| (0 for a channel that is 0 throughout)."""
    return np.maximum(y.max(axis=0) - y.min(axis=0), ROUNDOFF_FLOOR * np.abs(y).max(axis=0))


def _failed_divisors(mis: np.ndarray, p: int) -> float:
    """Smallest mismatch mis[q] over the proper divisors q of p (all above rtol, or p would not
    be tried), inf for p = 1. mis: (p_max + 1,), -."""
    return min((mis[q] for q in range(1, p) if p % q == 0), default=np.inf)


def _check_arguments(n_lobes: int, rtol: float, max_order: float, scale: np.ndarray | None) -> None:
    """Raise ValueError naming the argument that makes a classification meaningless (an rtol
    of nan would silently accept nothing, a max_order of nan or inf fail deep in numpy)."""
    if int(n_lobes) != n_lobes or n_lobes < 1:
        raise ValueError(f"n_lobes must be a whole number >= 1, got {n_lobes}")
    if not (np.isfinite(rtol) and rtol >= 0.0):
        raise ValueError(f"rtol must be a finite number >= 0, got {rtol}")
    if not (np.isfinite(max_order) and max_order * n_lobes >= 1.0 - 1e-9):
        raise ValueError(f"max_order must be finite and >= 1 / n_lobes = {1.0 / n_lobes:g} (p = 1 casing period), "
                         f"got {max_order}")
    if scale is not None and (np.asarray(scale, float) < 0.0).any():
        raise ValueError(f"scale is a range and must be >= 0, got {scale}")


def _code(p: int, n_lobes: int) -> PeriodClass:
    if p == 1:
        return PeriodClass.CASING
    if p == n_lobes:
        return PeriodClass.REVOLUTION
    return PeriodClass.SUBHARMONIC if p > n_lobes else PeriodClass.SUPERHARMONIC
