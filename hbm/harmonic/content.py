"""Dynamical content of a periodic solution (section 3.4): which modes and which harmonics
carry it.

Modal contributions, eqs. (32)-(33): gamma_j(t) = Phi_j^T M x(t) with the ROM's own modes
(eigenvectors of the ROM's K and M, mass-normalised), and ||gamma_j||_inf,rel =
max_t |gamma_j| / sum_k max_t |gamma_k| over all n ROM modes (the paper's n = 3 n_b + eta,
its ROM's size), so that the contributions of one point sum to 1. The ROM's modes, not the
full model's: the HBM solution lives in the ROM's n dof, where the ROM's modes are an exact
basis (the contributions of all modes add up to the whole motion). With the Craig-Bampton
basis T (boundary dof: static constraint modes, not modal coordinates), gamma_j is exactly
(T Phi_j)^T M_full (T x), the projection of the recovered full field on the ROM's Ritz
approximation T Phi_j of the full model's mode j, with the full model's M. Against the full
model's own modes it is as exact as those Ritz vectors: on the coarse rotor 67 ROM, at the
largest-amplitude point of a DLFT isola, the peaks of 1B, 2B, 1T and the 4th mode agree with
the full model's within 2e-6, 3e-4, 7e-4 and 3.5e-3 (mode 12: 48 %), their relative
contributions within 7e-5 (tests/hbm/test_content_full_model.py). Modes 13 to n of the ROM
are dominated by its boundary dof; their share is in the denominator of eq. (33), as in the
paper's. The ROM is built without rotation effects, so these are the modes at rest.

max_t is the maximum over the whole period (the sup norm that eq. (33)'s N_t samples stand
for): branch_content takes it from the harmonics, refined to round-off, not from the AFT
grid's N_t samples, whose maximum of a harmonic k falls short by up to 1 - cos(pi gcd(k,
N_t) / N_t) (29 % at k = N_t / 4) and made the content depend on n_time and on the basis
(the same orbit in the bases of Omega and Omega / 2 gave other contributions).
modal_contributions, given samples only, takes their maximum (eq. 33 as written).

Harmonic contributions, eq. (34): |c_k| = sqrt(a_k^2 + b_k^2) of the leading-edge radial
displacement, k = 0 .. N_h (|c_0| = |mean|, the paper's a_0 / 2 of eq. 2), in m. k is the
index in the residual's basis: in a subharmonic basis (nu > 1) the harmonic k oscillates at
k Omega / nu (k = nu is the rotation frequency Omega; isolas.h5 stores nu as the branch's
attribute `subharmonic`).
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


def _check_modes(M: np.ndarray, modes: np.ndarray) -> None:
    """ValueError unless modes^T M modes = I (to 1e-6): eq. (32) reads modal coordinates only
    with mass-normalised shapes; others (numpy's eig gives unit Euclidean norm) scaled each
    contribution by their own norm, silently."""
    gram = modes.T @ M @ modes
    err = float(np.abs(gram - np.eye(len(gram))).max(initial=0.0))
    if not err <= 1e-6:
        raise ValueError(f"modes must be mass-normalised and M-orthogonal (modes^T M modes = I, rom_modes); "
                         f"|modes^T M modes - I| reaches {err:.3g}")


def _check_shapes(name: str, x: np.ndarray, M: np.ndarray, modes: np.ndarray, what: str) -> None:
    n = M.shape[0] if M.ndim == 2 else -1
    if M.ndim != 2 or M.shape != (n, n) or x.ndim < 2 or x.shape[-1] != n or modes.ndim != 2 \
            or modes.shape[0] != n:
        raise ValueError(f"{name} needs x {what}, M (n, n), modes (n, n_modes); got x "
                         f"{x.shape}, M {M.shape}, modes {modes.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError(f"{name}: the motion x holds NaN or inf values")
    _check_modes(M, modes)


def _relative(peak: np.ndarray) -> np.ndarray:
    """Eq. (33) from the peaks (..., n_modes): 0 for a motion at rest (0 / 0: no contribution)."""
    total = peak.sum(axis=-1, keepdims=True)
    return np.divide(peak, total, out=np.zeros_like(peak), where=total > 0)


def modal_contributions(x: np.ndarray, M: np.ndarray, modes: np.ndarray) -> np.ndarray:
    """Relative modal contributions of eqs. (32)-(33), (..., n_modes), summing to 1.

    x: displacement of the ROM dof over one period, (..., N_t, n), m; the maximum is over these
    samples (eq. 33 as written; modal_contributions_of_harmonics takes the period's). M: (n,
    n), kg. modes: mass-normalised mode shapes (n, n_modes) (rom_modes; all n of them for eq.
    33, whose sum runs over every mode: fewer share 1 among themselves). A motion at rest gives 0.
    Raises ValueError for a motion that is not finite (NaN or inf: no contribution can be
    told, and it is no motion at rest either), for modes that are not mass-normalised, or
    whose shapes do not match.
    """
    x = np.asarray(x, dtype=float)
    M = np.asarray(M, dtype=float)
    modes = np.asarray(modes, dtype=float)
    _check_shapes("modal_contributions", x, M, modes, "(..., N_t, n)")
    gamma = x @ (M @ modes)  # eq. (32), (..., N_t, n_modes)
    return _relative(np.abs(gamma).max(axis=-2))


def peak_magnitudes(coeffs: np.ndarray) -> np.ndarray:
    """max over the period of |g(tau)|, (m,), of m real trigonometric polynomials g given by
    their harmonics coeffs (2 N_h + 1, m), eq. (5) order [c_0, a_1, b_1, ..., a_Nh, b_Nh].

    Sampled on 16 (N_h + 1) points (the nearest sample to the maximum is within 1 - (pi /
    16)^2 / 2 of it), then the largest sampled local maxima of g and of -g refined by
    Newton's method on g' = 0 within one sample of where they started: to round-off,
    whatever the AFT grid (from within a sample the phase error k dtau <= pi / 16 falls
    quadratically: four steps reach round-off; eight gave the same contributions to 1e-16 on
    the coarse rotor 67 NFRC, for 14 % more time). Every value taken is |g| somewhere, so the result never exceeds the true maximum."""
    c = np.asarray(coeffs, dtype=float)
    if c.ndim != 2 or c.shape[0] % 2 != 1:
        raise ValueError(f"coeffs must have shape (2 N_h + 1, m), got {c.shape}")
    nh = (c.shape[0] - 1) // 2
    if nh == 0 or c.shape[1] == 0:
        return np.abs(c[0]).copy()
    L = 16 * (nh + 1)
    spec = np.zeros((nh + 1, c.shape[1]), dtype=complex)
    spec[0] = c[0]
    spec[1:] = 0.5 * (c[1::2] - 1j * c[2::2])
    g = np.fft.irfft(L * spec, n=L, axis=0)  # (L, m): c_0 + sum a_k cos k tau + b_k sin k tau
    a = np.abs(g)
    best = a.max(axis=0)
    # the largest local maxima of g and of -g, four of each: the sampling can rank every
    # peak of one sign above the true maximum of the other (a harmonic whose positive peaks
    # all fall on samples and negative ones half-way between)
    ranked = []
    for y in (g, -g):
        local = (y >= np.roll(y, 1, axis=0)) & (y >= np.roll(y, -1, axis=0))
        ranked.append(np.argsort(np.where(local, -y, np.inf), axis=0)[:4])
    ranked = np.concatenate(ranked)  # (<= 8, m)
    dtau = 2.0 * np.pi / L
    t0 = (ranked * dtau).T  # (m, C) starting angles
    k = np.arange(1, nh + 1)
    ak, bk = c[1::2].T[:, None, :], c[2::2].T[:, None, :]  # (m, 1, N_h)
    tt = t0[..., None]  # (m, C, 1)
    for _ in range(4):
        cs, sn = np.cos(k * tt), np.sin(k * tt)
        d1 = np.sum(k * (bk * cs - ak * sn), axis=-1)
        d2 = -np.sum(k ** 2 * (ak * cs + bk * sn), axis=-1)
        step = np.divide(d1, d2, out=np.zeros_like(d1), where=d2 != 0)
        tt = np.clip(tt[..., 0] - step, t0 - dtau, t0 + dtau)[..., None]
    val = c[0][:, None] + np.sum(ak * np.cos(k * tt) + bk * np.sin(k * tt), axis=-1)  # (m, C)
    return np.maximum(best, np.abs(val).max(axis=1))


def modal_contributions_of_harmonics(coeffs: np.ndarray, M: np.ndarray, modes: np.ndarray) -> np.ndarray:
    """Relative modal contributions of eqs. (32)-(33), (n_modes,), summing to 1, with max_t
    the maximum over the whole period (peak_magnitudes), not over a time grid.

    coeffs: harmonics of the ROM dof, (2 N_h + 1, n), m, eq. (5) order (expand_harmonics).
    M, modes: as in modal_contributions (mass-normalised). A motion at rest gives 0; a motion
    that is not finite raises ValueError."""
    c = np.asarray(coeffs, dtype=float)
    M = np.asarray(M, dtype=float)
    modes = np.asarray(modes, dtype=float)
    _check_shapes("modal_contributions_of_harmonics", c, M, modes, "(2 N_h + 1, n)")
    if c.ndim != 2 or c.shape[0] % 2 != 1:
        raise ValueError(f"coeffs must have 2 N_h + 1 rows, got shape {c.shape}")
    return _relative(peak_magnitudes(c @ (M @ modes)))  # eq. (32) harmonic by harmonic, then (33)


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
    displacement, m (eq. 34; column k is harmonic k of the residual's basis, k Omega / nu,
    nu = residual.nu), "mode_frequencies": (n,), rad/s}. max_t is over the whole period
    (modal_contributions_of_harmonics), whatever the residual's N_t. A point whose unknowns
    are not finite (NaN or inf) gets NaN contributions.
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
        modal[i] = modal_contributions_of_harmonics(full, rom.M, phi)
        harmonic[i] = harmonic_contributions(residual.to_coefficients(ui)[:, 0])
    return {"modal_contribution": modal, "harmonic_contribution": harmonic, "mode_frequencies": freq}
