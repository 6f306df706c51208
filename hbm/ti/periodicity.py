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
    smallest one over all tried p when NONE, -.
    """

    code: PeriodClass
    period: int
    order: float
    mismatch: float


def classify_period(sections: np.ndarray, n_lobes: int = 2, rtol: float = 1e-2, max_order: float = 10.0,
                    scale: np.ndarray | None = None) -> Periodicity:
    """Smallest period of a sequence of Poincare sections, in casing periods.

    sections: samples y_k at t_k = t_0 + k T_c, (n_sec,) or (n_sec, n_channels), any unit;
    each channel is scaled by `scale` (n_channels,), same unit: the signal's range over the
    whole window, which the sections alone may not see; default: the range of the sections.
    Channels of zero scale are ignored.
    n_lobes: n_l, casing periods per revolution. rtol: accepted mismatch relative to the
    range, -. max_order: largest nu = Omega / omega still called subharmonic, -.
    A period p is accepted when every section of the window repeats after p casing periods:
    max_k max_ch |y_{k+p} - y_k| / range_ch <= rtol over k = 0 .. n_sec - 1 - p, and only
    p <= (n_sec - 1) / 2 are tried so that each accepted period is seen at least twice.
    A signal of zero range (constant) has period 1; one with a value (or a scale) that is not
    finite has none (NONE, mismatch nan).
    """
    y = np.asarray(sections, dtype=float)
    if y.ndim == 1:
        y = y[:, None]
    n_sec = y.shape[0]
    if n_sec < 3:
        raise ValueError(f"need at least 3 Poincare sections, got {n_sec}")
    rng = y.max(axis=0) - y.min(axis=0) if scale is None else np.broadcast_to(np.asarray(scale, float), y.shape[1:])
    if not (np.isfinite(y).all() and np.isfinite(rng).all()):  # a march that blew up repeats nothing
        return Periodicity(code=PeriodClass.NONE, period=0, order=float("nan"), mismatch=float("nan"))
    keep = rng > 0.0
    if not keep.any():
        return Periodicity(code=PeriodClass.CASING, period=1, order=1.0 / n_lobes, mismatch=0.0)
    y = y[:, keep] / rng[keep]
    p_max = min(int(np.floor(max_order * n_lobes + 1e-9)), (n_sec - 1) // 2)
    best = np.inf
    for p in range(1, p_max + 1):
        mis = float(np.abs(y[p:] - y[:-p]).max())
        best = min(best, mis)
        if mis <= rtol:
            return Periodicity(code=_code(p, n_lobes), period=p, order=p / n_lobes, mismatch=mis)
    return Periodicity(code=PeriodClass.NONE, period=0, order=float("nan"), mismatch=best)


def _code(p: int, n_lobes: int) -> PeriodClass:
    if p == 1:
        return PeriodClass.CASING
    if p == n_lobes:
        return PeriodClass.REVOLUTION
    return PeriodClass.SUBHARMONIC if p > n_lobes else PeriodClass.SUPERHARMONIC
