"""Dynamical content of a periodic solution (section 3.4): which modes and which harmonics
carry it.

Modal contributions, eqs. (32)-(33): gamma_j(t) = Phi_j^T M x(t) with the ROM's own modes
(eigenvectors of the ROM's K and M, mass-normalised), and ||gamma_j||_inf,rel =
max_t |gamma_j| / sum_k max_t |gamma_k| over all n ROM modes, so that the contributions
of one point sum to 1. The ROM's modes, not the full model's: the HBM solution lives in
the ROM's n dof, where the ROM's modes are an exact basis (the contributions of all modes
add up to the whole motion), and the Craig-Bampton ROM reproduces the full model's first
modes (the ones that matter here, 1B, 2B, 1T, ...) to the accuracy the rom stage reports.
The ROM is built without rotation effects, so these are the modes at rest.

Harmonic contributions, eq. (34): |c_k| = sqrt(a_k^2 + b_k^2) of the leading-edge radial
displacement, k = 0 .. N_h (|c_0| = |mean|), in m. In a subharmonic basis (nu > 1) the
harmonic k oscillates at k Omega / nu.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg as sla



def rom_modes(K: np.ndarray, M: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eigenfrequencies (n,), rad/s, ascending, and mass-normalised mode shapes (n, n)
    (column j: mode j, Phi^T M Phi = I) of K (n, n), N/m, and M (n, n), kg.

    A negative eigenvalue w^2 is round-off, and taken as 0, down to -n eps cond(M) max|w^2|
    (the bound of rom.model.eigenfrequencies, repeated here: hbm reads a ROM file, possibly
    from another FE code, and does not import rom/); below it, ValueError: K is indefinite,
    and a frequency of 0 would hide it."""
    M = np.asarray(M, dtype=float)
    lam, phi = sla.eigh(np.asarray(K, dtype=float), M)
    m = np.linalg.eigvalsh(M)
    tol = len(lam) * np.finfo(float).eps * (m[-1] / m[0]) * float(np.abs(lam).max(initial=0.0))
    if len(lam) and lam[0] < -tol:
        raise ValueError(f"K is not positive semi-definite: (K, M) has the eigenvalue w^2 = {lam[0]:.6g} "
                         f"rad^2/s^2, below the round-off bound -{tol:.3g} (n eps cond(M) max|w^2|): the ROM "
                         f"is not a clamped, stable structure or K is corrupt")
    return np.sqrt(np.maximum(lam, 0.0)), phi


def modal_contributions(x: np.ndarray, M: np.ndarray, modes: np.ndarray) -> np.ndarray:
    """Relative modal contributions of eqs. (32)-(33), (..., n_modes), summing to 1.

    x: displacement of the ROM dof over one period, (..., N_t, n), m. M: (n, n), kg.
    modes: mass-normalised mode shapes (n, n_modes) (rom_modes). A motion at rest gives 0.
    Raises ValueError for a motion that is not finite (NaN or inf: no contribution can be
    told, and it is no motion at rest either) or whose shapes do not match.
    """
    x = np.asarray(x, dtype=float)
    M = np.asarray(M, dtype=float)
    modes = np.asarray(modes, dtype=float)
    n = M.shape[0] if M.ndim == 2 else -1
    if M.ndim != 2 or M.shape != (n, n) or x.ndim < 2 or x.shape[-1] != n or modes.ndim != 2 \
            or modes.shape[0] != n:
        raise ValueError(f"modal_contributions needs x (..., N_t, n), M (n, n), modes (n, n_modes); got x "
                         f"{x.shape}, M {M.shape}, modes {modes.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError("modal_contributions: the motion x holds NaN or inf values")
    gamma = x @ (M @ modes)  # eq. (32), (..., N_t, n_modes)
    peak = np.abs(gamma).max(axis=-2)
    total = peak.sum(axis=-1, keepdims=True)
    return np.divide(peak, total, out=np.zeros_like(peak), where=total > 0)


def harmonic_contributions(coeffs: np.ndarray) -> np.ndarray:
    """|c_k| of eq. (34), k = 0 .. N_h, (N_h + 1, ...), same unit as coeffs.

    coeffs: harmonics in eq. (5) order [c_0, a_1, b_1, ..., a_Nh, b_Nh], (2 N_h + 1, ...);
    an even number of rows (a cosine without its sine) raises ValueError."""
    c = np.asarray(coeffs, dtype=float)
    if c.ndim == 0 or c.shape[0] % 2 != 1:
        raise ValueError(f"coeffs must have 2 N_h + 1 rows [c_0, a_1, b_1, ..., a_Nh, b_Nh], got shape {c.shape}")
    return np.concatenate([np.abs(c[:1]), np.hypot(c[1::2], c[2::2])], axis=0)


def branch_content(residual, rom, unknowns: np.ndarray, omega: np.ndarray,
                   modes: tuple[np.ndarray, np.ndarray] | None = None) -> dict:
    """Modal and harmonic contributions at every point of a branch.

    residual: the branch's HarmonicBalanceResidual (hbm.harmonic.residual). rom: RomModel
    (K, M). unknowns: the points' unknowns, (m, n_u). omega: Omega of each point, (m,), rad/s.
    modes: rom_modes(rom.K, rom.M) when already computed.
    Returns {"modal_contribution": (m, n) relative contributions (eq. 33) of the n ROM modes
    in ascending frequency, "harmonic_contribution": (m, N_h + 1) |c_k| of the LE radial
    displacement, m (eq. 34), "mode_frequencies": (n,), rad/s}. The max over time is taken
    on the residual's AFT grid (N_t samples per period). A point whose unknowns are not
    finite (NaN or inf) gets NaN contributions.
    """
    freq, phi = rom_modes(rom.K, rom.M) if modes is None else modes
    basis = residual.basis
    u = np.asarray(unknowns, dtype=float).reshape(len(omega), -1)
    modal = np.empty((len(u), phi.shape[1]))
    harmonic = np.empty((len(u), basis.n_harmonics + 1))
    for i, (ui, wi) in enumerate(zip(u, np.asarray(omega, dtype=float))):
        if not (np.all(np.isfinite(ui)) and np.isfinite(wi)):
            modal[i], harmonic[i] = np.nan, np.nan
            continue
        full = residual.expand_harmonics(ui, float(wi))  # (2 N_h + 1, n), m
        modal[i] = modal_contributions(basis.to_time(full), rom.M, phi)
        harmonic[i] = harmonic_contributions(residual.to_coefficients(ui)[:, 0])
    return {"modal_contribution": modal, "harmonic_contribution": harmonic, "mode_frequencies": freq}
