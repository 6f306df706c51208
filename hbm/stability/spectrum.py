"""Floquet multipliers of an HBM orbit by Hill's method, with the selection of the physical
exponents by the harmonic centre of their eigenvectors (Lazarus and Thomas 2010).

Hill's truncated problem H(lam) p = 0 (hbm.stability.hill) with N harmonics has (2 N + 1)
eigenvalues per Floquet exponent: the exponent's family lam + i k w, whose eigenvectors are
the same periodic function's coefficients shifted by k harmonics. All members of a family
give the same multiplier exp(lam T), T = 2 pi / w; but only the members whose eigenvector
lies well inside the retained band are accurate: the truncation cuts the others. The
representative kept for each family is the member whose eigenvector's harmonic centre
k_bar = sum_k k |c_k|^2 / sum_k |c_k|^2 (complex-exponential coefficients c_k, k = -N..N)
is nearest 0 (|k_bar| <= 1/2), which is the member farthest from both truncation edges.

Why this and not the smallest |Im lam| (Moore 2005): Moore's rule takes the member with
|Im lam| <= w / 2 as the accurate one, which holds only when that member's eigenvector is
centred, i.e. for modes below ~w / 2. The blade's 2B, 1T and the ROM's constraint modes
(up to 2e6 rad/s against w = 800..4000 rad/s) have that member's eigenvector centred at
|k| ~ omega_j / w, near or beyond the truncation edge, where the truncation moves the
eigenvalue. Measured on the rotor 67 ROM (DLFT, Omega = 2000 rad/s, N_h = 10, dense Hill
matrix): the members with |Im| <= w / 2 include exponents with Re = +4.1 and +2.7 1/s
(k_bar = 1.9 and 3.1) whose centred family members have Re = -1.9 and below: Moore's rule
counts the orbit unstable by these truncation artefacts alone; and at N_h = 20 (RL,
Omega = 1969 rad/s) one family has Re = +3.8 1/s on its member nearest 0 (k_bar = -1.1)
and -1.5 1/s on its centred member. Against shooting (tests/hbm/test_stability_hill.py)
the centred rule reproduces the multipliers to 1e-12 (Duffing) and 1e-5 (RL obstacle).

Two ways to compute the spectrum:
- dense: every eigenvalue of the linearised quadratic problem (small operators, tests);
- Arnoldi: shift-invert at lam = 0 (ARPACK) with H(0)^-1 = the HBM Jacobian's inverse
  (hbm.stability.hill.HillSolver), the n_eig eigenvalues nearest 0. Every family has a
  member with |Im lam| <= w / 2, so every family with |Re lam| < delta has one within
  |lam| <= sqrt(delta^2 + w^2 / 4): with rho the largest |lam| found, every multiplier of
  modulus between exp(-delta T) and exp(+delta T), delta = sqrt(rho^2 - w^2 / 4), is in the
  result (FloquetSpectrum.modulus_floor and .modulus_ceiling). A multiplier beyond the
  ceiling can be missed, and with it the orbit's instability: on the coarse rotor 67 NFRC
  at 1335-1341 rad/s a multiplier mu ~ -21 (log|mu| 3.04-3.07, ceilings 2.64-2.90 with 40
  eigenvalues) is the 41st nearest 0, and the orbit came out stable. orbit_spectrum
  widens the window until a stable verdict holds up to min_ceiling (MIN_CEILING); the
  stability monitor widens where a large multiplier of a neighbour disappears
  (hbm.stability.monitor). No finite window rules out a multiplier beyond its ceiling.
  The member found nearest 0 need not be the centred one; its multiplier is the family's,
  its accuracy that of its eigenvector's distance to the truncation edges
  (FloquetSpectrum.centred, .edge_energy say how far).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla
import scipy.sparse.linalg as spla

from hbm.stability.hill import HillOperator, HillSolver

#: a multiplier is unstable when log|mu| = Re(lam) T exceeds this (a numerical zero: the
#: exponents of a converged orbit carry ~1e-10 relative error; the margin is for the
#: multiplier +1 of an exact fold, which must not count).
GROWTH_TOL = 1e-6
#: dense_spectrum solves the standard problem of B^-1 A when the second-order term's condition
#: number is below this (eigenvalues then carry ~cond * eps relative error, 1e-8 at most),
#: the QZ of the pencil otherwise (massless dof, DLFT's constrained rows). On rotor 67 at
#: N_h = 5 (cond ~3e6) the eigen-solve takes a tenth of QZ's time at size 429 and a whole
#: analysis a third at size 195, with quadratic residuals of 1e-14 against QZ's 1e-10.
DENSE_COND_MAX = 1e8


@dataclass(frozen=True, eq=False)
class FloquetSpectrum:
    """Floquet exponents and multipliers of a periodic orbit over the period of its basis.

    omega: fundamental of the basis, rad/s; period = 2 pi / omega, s (the orbit's minimal
    period when the operator was restricted to it, see hbm.stability.hill.restrict).
    exponents: (m,) complex, 1/s: one per multiplier, the family's centred member
    lam + i round(k_bar) omega (Im is defined modulo omega; the centred member's is the
    mode's dominant angular frequency). Sorted by decreasing |multiplier|.
    multipliers: (m,) complex, exp(exponent * period).
    centred: (m,) bool, whether that member's eigenvector has |k_bar| <= 1/2.
    edge_energy: (m,) fraction of the eigenvector's energy in the outer tenth of the band
    on each side (truncation quality; ~0 for a converged eigenvector).
    eigenvectors: (m, 2 N + 1, n) complex: p(t)'s coefficients in eq. (5) order for the
    reported (centred) member: the Floquet mode is exp(exponent t) p(t) (unit 2-norm; the
    coefficients shifted out of the band by the centring are lost when the member found was
    not the centred one).
    modulus_floor: every multiplier with modulus_floor < |mu| < 1 / modulus_floor is listed
    (0: all of them; see modulus_ceiling).
    method: "dense" or "arnoldi". note: why the result may be incomplete ("" if not).
    complete: False when ARPACK stopped short of the eigenvalues asked for (see decided).
    """

    omega: float
    exponents: np.ndarray
    multipliers: np.ndarray
    centred: np.ndarray
    edge_energy: np.ndarray
    eigenvectors: np.ndarray = field(repr=False)
    modulus_floor: float = 0.0
    method: str = "dense"
    note: str = ""
    complete: bool = True

    @property
    def period(self) -> float:
        return 2.0 * np.pi / self.omega

    @property
    def modulus_ceiling(self) -> float:
        """1 / modulus_floor (inf when every multiplier is listed): a multiplier of larger
        modulus may be missing, so a stable verdict holds for |mu| below this only."""
        return 1.0 / self.modulus_floor if self.modulus_floor > 0.0 else np.inf

    @property
    def unstable(self) -> np.ndarray:
        """(m,) bool: multipliers outside the unit circle (log|mu| > GROWTH_TOL)."""
        return self.exponents.real * self.period > GROWTH_TOL

    @property
    def decided(self) -> bool:
        """Whether the multipliers give a verdict. Not when ARPACK stopped short (complete
        False: the eigenvalues it did not converge may be the unstable ones, and no window
        bounds them) or when none is listed (every family dropped as a truncation artefact,
        or no eigenvalue at all): note says why; nor when an Arnoldi window bounds nothing
        (modulus_floor 1: its farthest eigenvalue lies within omega / 2 of 0, so a family
        centred at Im = omega / 2, a multiplier near -1, may lie just outside it). A dense
        spectrum that drops some families keeps the verdict of the others, and its note says so."""
        return (self.complete and len(self.multipliers) > 0
                and not (self.method == "arnoldi" and self.modulus_floor >= 1.0))

    @property
    def undecided_reason(self) -> str:
        """Why the multipliers give no verdict, in words ("" when decided)."""
        if self.decided:
            return ""
        if not self.complete or not len(self.multipliers):
            return self.note or "no multiplier"
        return ((self.note + "; " if self.note else "")
                + "the Arnoldi window bounds no multiplier (modulus floor 1: its farthest eigenvalue lies "
                "within omega / 2 of 0)")

    @property
    def n_unstable(self) -> int:
        """Number of multipliers outside the unit circle (with multiplicity: a complex pair is 2);
        -1 (unknown) when not decided, whatever the listed ones say."""
        return int(np.count_nonzero(self.unstable)) if self.decided else -1

    @property
    def stable(self) -> bool:
        """No multiplier outside the unit circle, and a decided spectrum (False when not decided)."""
        return self.n_unstable == 0

    @property
    def largest_modulus(self) -> float:
        """The largest |multiplier|, - (0 when none is listed)."""
        return float(np.abs(self.multipliers[0])) if len(self.multipliers) else 0.0

    def leading(self, k: int) -> np.ndarray:
        """The k largest |multipliers|, (k,), padded with nan, -."""
        out = np.full(k, np.nan)
        mods = np.abs(self.multipliers[:k])
        out[: len(mods)] = mods
        return out


# -- harmonic bookkeeping -------------------------------------------------------------------
def exponential_coefficients(P: np.ndarray) -> np.ndarray:
    """Complex-exponential coefficients c_k, k = -N..N (index k + N), of p(t) = P_0 + sum_k
    P_ak cos(k t) + P_bk sin(k t): P (..., 2 N + 1, n) eq. (5) order -> (..., 2 N + 1, n)."""
    P = np.asarray(P)
    nh = (P.shape[-2] - 1) // 2
    c = np.empty(P.shape, dtype=complex)
    c[..., nh, :] = P[..., 0, :]
    c[..., nh + 1:, :] = 0.5 * (P[..., 1::2, :] - 1j * P[..., 2::2, :])
    c[..., :nh, :] = (0.5 * (P[..., 1::2, :] + 1j * P[..., 2::2, :]))[..., ::-1, :]
    return c


def real_coefficients(c: np.ndarray) -> np.ndarray:
    """Inverse of exponential_coefficients."""
    nh = (c.shape[-2] - 1) // 2
    P = np.empty(c.shape, dtype=complex)
    cp, cm = c[..., nh + 1:, :], c[..., :nh, :][..., ::-1, :]
    P[..., 0, :] = c[..., nh, :]
    P[..., 1::2, :] = cp + cm
    P[..., 2::2, :] = 1j * (cp - cm)
    return P


def shift_member(P: np.ndarray, m: int) -> np.ndarray:
    """Eigenvector of the family member lam + i m omega from that of lam: p(t) exp(-i m omega t),
    i.e. c_k -> c_{k+m} (coefficients shifted out of the band are lost, zeros come in)."""
    c = exponential_coefficients(P)
    out = np.zeros_like(c)
    n = c.shape[-2]
    # |m| >= n shifts the whole band out (an Arnoldi pair m omega apart, m > 2 N): zeros
    if 0 <= m < n:
        out[..., : n - m, :] = c[..., m:, :]
    elif -n < m < 0:
        out[..., -m:, :] = c[..., : n + m, :]
    return real_coefficients(out)


def harmonic_centre(P: np.ndarray, n_edge: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(k_bar, edge energy) of eigenvectors P (m, 2 N + 1, n): the energy-weighted mean
    harmonic of the complex-exponential coefficients, and the energy fraction in the outer
    n_edge harmonics of each side (default max(1, N // 10): the outer tenth of the band)."""
    c = exponential_coefficients(P)
    e = np.sum(np.abs(c) ** 2, axis=-1)  # (m, 2 N + 1)
    nh = (e.shape[-1] - 1) // 2
    n_edge = max(1, nh // 10) if n_edge is None else n_edge
    k = np.arange(-nh, nh + 1)
    tot = e.sum(axis=-1)
    edge = (e[..., :n_edge].sum(axis=-1) + e[..., -n_edge:].sum(axis=-1)) / tot
    return (e @ k) / tot, edge


# -- selection ------------------------------------------------------------------------------
#: how far (in units of omega, per harmonic of shift) a family member's real part may lie from
#: another's in the Arnoldi window (see _families): on rotor 67 at N_h = 40, 1.0-1.1e-3 omega
#: per harmonic with DLFT and 1.3-2.6e-3 with RL, at one RL point 1.1e-2 (1464.2 rad/s on the
#: coarse NFRC: beyond this, and the widened window calls that orbit unstable where the dense
#: spectrum does not). RL's Lanczos filter on the force rows is not invariant under a shift
#: of the harmonics, the likely reason why RL drifts more (not isolated).
MEMBER_DRIFT = 4e-3


def _near_half(lam: np.ndarray, omega: float) -> np.ndarray:
    """(m,) bool: exponents lam (m,) 1/s with Im lam = omega / 2 modulo omega to 1e-2 omega,
    those of (near-)real negative multipliers."""
    return np.abs((np.imag(lam) / omega) % 1.0 - 0.5) < 1e-2


def _real_tolerance(a: complex, b: complex, m: int, omega: float) -> float:
    """How far apart (1/s) the real parts of Arnoldi eigenvalues a and b, m harmonics apart,
    may lie and still be members of one family (see _families): MEMBER_DRIFT per harmonic,
    but 2e-3 omega when both are near-real negative multipliers (Im = omega / 2 modulo omega,
    to 1e-2 omega), where two families just born from a complex pair have parallel
    eigenvectors and only their real parts tell them apart."""
    return (2e-3 if _near_half(np.array([a, b]), omega).all() else MEMBER_DRIFT * max(1, abs(m))) * omega


def _families(lam: np.ndarray, P: np.ndarray, omega: float, max_edge: float, dense: bool):
    """One representative per exponent family: (exponents, edge, vectors, centred) of the
    representatives (the centred member's exponent lam + i round(k_bar) omega and its
    eigenvector).

    dense (all eigenvalues at hand): every family's centred member (|k_bar| <= 1/2) is
    among them, so those are the representatives (Lazarus and Thomas); the rest, including
    truncation artefacts (eigenvalues whose eigenvector no shift brings to the band's
    centre), is dropped. The family of a real negative multiplier has two members at
    |k_bar| = 1/2 (lam and conj(lam) = lam - i omega): one multiplier, counted once. The
    truncation moves Im lam off omega / 2 (by 3e-6 omega for a Mathieu oscillator at
    N_h = 2), so that lam - i omega is not conj(lam) any more; conj(lam), an eigenvalue of
    the real problem to round-off, is the member merged then.
    Otherwise (the Arnoldi window): eigenpair i joins the family of representative j when
    lam_i = lam_j + i m omega for an integer m != 0, to 1e-2 omega in the imaginary part and
    _real_tolerance in the real part, and p_i is parallel to p_j shifted by m harmonics
    (|cos| > 0.9). The truncation moves the members' real parts with the shift
    (MEMBER_DRIFT says by how much on rotor 67): a tolerance that ignores the shift keeps
    far members apart, as unstable "families" that the dense spectrum does not have.
    Between two near-real negative multipliers the tolerance stays tight: two families just
    born from a complex pair there have nearly parallel eigenvectors, and merging them would
    hide the period doubling.
    """
    kbar, edge = harmonic_centre(P)
    centred = np.abs(kbar) <= 0.5 + 1e-3  # 1e-3: round-off and the truncation's shift of the centre
    order = np.argsort(np.abs(kbar))
    # a truncation artefact: an eigenvector at the truncation edge
    keep = np.isfinite(lam) & (edge <= max_edge) & (centred if dense else True)
    cand = order[keep[order]]
    if dense:  # only the two centred members of a real negative multiplier's family are one
        lc = lam[cand]
        d = lc[:, None] - lc[None, :]
        m = np.round(d.imag / omega)
        dup = (m != 0) & (np.abs(d.imag - m * omega) <= 1e-6 * omega) & (np.abs(d.real) <= 1e-6 * omega)
        half = _near_half(lc, omega)
        dup |= (m != 0) & half[:, None] & half[None, :] & (np.abs(lc[:, None] - np.conj(lc)[None, :]) <= 1e-6 * omega)
        kept = np.zeros(len(cand), dtype=bool)
        for c in range(len(cand)):
            kept[c] = not dup[c, :c][kept[:c]].any()
        reps = list(cand[kept])
    else:
        reps = []
        for i in cand:
            a = P[i].reshape(-1)
            same = False
            for j in reps:
                d = lam[i] - lam[j]
                m = int(np.round(d.imag / omega))
                # m = 0 is never one family: it has one member per shift, and two real
                # exponents of parallel eigenvectors (a saddle's pair beside a fold, +-1e-3 omega)
                # are two multipliers, one of them unstable
                if m != 0 and abs(d.imag - m * omega) <= 1e-2 * omega \
                        and abs(d.real) <= _real_tolerance(lam[i], lam[j], m, omega):
                    b = shift_member(P[j], m).reshape(-1)
                    same = abs(np.vdot(a, b)) > 0.9 * np.linalg.norm(a) * np.linalg.norm(b)
                if same:
                    break
            if not same:
                reps.append(i)
    idx = np.array(reps, dtype=int)
    shifts = np.round(kbar[idx]).astype(int)
    ex = lam[idx] + 1j * shifts * omega
    vec = P[idx].copy()
    for k in np.unique(shifts):  # one product per shift (shift_member is elementwise)
        vec[shifts == k] = shift_member(P[idx[shifts == k]], int(k))
    return ex, edge[idx], vec, centred[idx]


def _spectrum(lam, P, H: HillOperator, floor: float, method: str, note: str, max_edge: float,
              complete: bool = True) -> FloquetSpectrum:
    P = np.asarray(P).reshape(len(lam), H.n_c, H.n)
    norms = np.linalg.norm(P.reshape(len(lam), H.n_c * H.n), axis=1)
    P = P / np.where(norms > 0, norms, 1.0)[:, None, None]
    ex, edge, vec, centred = _families(np.asarray(lam), P, H.omega, max_edge, dense=method == "dense")
    if len(lam) and not len(ex):  # every eigenvector at the truncation edge: say so, claim nothing
        note = (note + "; " if note else "") + "no eigenvector inside the harmonic band (too few harmonics)"
        floor = 1.0
    elif not len(lam) and not note:
        note = "no eigenvalue"
    elif method == "dense" and len(ex) < round(len(lam) / H.n_c):
        # all eigenvalues at hand: one family per 2 N + 1 of them, and a family dropped whole
        # (no member inside the band) is a multiplier missing from the verdict. The verdict of
        # the others stands: a rule on the dropped families' members would read the truncation
        # artefacts among them (log|mu| up to ~80 on the coarse rotor 67 ROM at low N_h) as growth
        note = (note + "; " if note else "") + (
            f"{round(len(lam) / H.n_c) - len(ex)} of {round(len(lam) / H.n_c)} exponent families have no "
            "eigenvector inside the harmonic band (too few harmonics): their multipliers are missing")
    T = 2.0 * np.pi / H.omega
    mu = np.exp(ex * T)
    order = np.argsort(-np.abs(mu), kind="stable")
    return FloquetSpectrum(omega=H.omega, exponents=ex[order], multipliers=mu[order],
                           centred=centred[order], edge_energy=edge[order], eigenvectors=vec[order],
                           modulus_floor=floor, method=method, note=note, complete=complete)


def dense_spectrum(H: HillOperator, max_edge: float = 0.05) -> FloquetSpectrum:
    """Every Floquet multiplier from the dense linearised Hill problem (A - lam B) z = 0,
    z = [p; lam p]: for small operators (H.size up to ~1000: the eigen-solve is O(size^3);
    standard on B^-1 A, or QZ when L2 is near singular, see DENSE_COND_MAX).

    max_edge: families whose best member keeps more than this energy fraction in the
    outer harmonics are truncation artefacts and dropped. With all eigenvalues at hand the
    representatives are the centred members (see _families): the 2 n exponents of an n-dof
    system (Lazarus and Thomas).
    """
    L0, L1, L2 = H.dense()
    n = H.size
    I = np.eye(n)
    Z = np.zeros((n, n))
    A = np.block([[Z, I], [-L0, -L1]])
    if np.linalg.cond(L2) < DENSE_COND_MAX:
        lam, V = np.linalg.eig(np.vstack([A[:n], np.linalg.solve(L2, A[n:])]))
    else:
        lam, V = sla.eig(A, np.block([[I, Z], [Z, L2]]))
    # infinite eigenvalues (massless dof, DLFT's constrained rows) come out of QZ as inf or
    # as ~1/eps; no Floquet exponent of the model is a million times the fundamental
    ok = np.isfinite(lam) & (np.abs(lam) < 1e6 * H.omega)
    return _spectrum(lam[ok], V[:n, ok].T, H, 0.0, "dense", "", max_edge)


def arnoldi_spectrum(H: HillOperator, n_eig: int = 40, solver: HillSolver | None = None, tol: float = 1e-9,
                     max_edge: float = 0.05) -> FloquetSpectrum:
    """The Floquet multipliers from the n_eig Hill eigenvalues nearest 0 (shift-invert
    Arnoldi, ARPACK): every multiplier above FloquetSpectrum.modulus_floor (see the module
    doc). solver: H(0)^-1 (built here when not given). n_eig = 40: on the rotor 67 ROM at
    N_h = 40 in the orbit's T / 2 basis, modulus_floor is 0.05 to 0.15 (all multipliers that
    can come near the unit circle) for about 0.13 s CPU (~100 solves; fewer eigenvalues leave
    rho < w / 2 there, i.e. no floor at all: n_eig = 24 and 30 gave modulus_floor 1).
    """
    S = solver or HillSolver(H)
    n = H.size
    k = min(n_eig, 2 * n - 2)

    def op(z):
        return np.concatenate([-S(H.tail(z[:n], z[n:])), z[:n]])

    A = spla.LinearOperator((2 * n, 2 * n), matvec=op, dtype=float)
    note, complete = "", True
    try:
        # a fixed start vector: ARPACK's own comes from a seed that every earlier eigs call
        # advances, and ill-conditioned multipliers far outside the unit circle (|mu| 4 to
        # 3000 on rotor 67) then moved by 1-2 %, enough to change a bifurcation's kind
        # from one run to another with the same inputs
        v0 = np.random.default_rng(0).standard_normal(2 * n)
        theta, V = spla.eigs(A, k=k, ncv=min(2 * n, 2 * k + 1), tol=tol, maxiter=20 * n, v0=v0)
    except spla.ArpackNoConvergence as exc:
        # the converged ones are exact but need not be the k nearest 0: no verdict (decided)
        theta, V = exc.eigenvalues, exc.eigenvectors
        note, complete = f"ARPACK converged {len(theta)} of {k} eigenvalues", False
    good = np.abs(theta) > 0
    lam = 1.0 / theta[good]
    P = V[:n, good].T
    if note or not len(lam):
        floor = 1.0  # nothing guaranteed about the missing ones
    else:
        rho = np.abs(lam).max()
        delta = np.sqrt(max(rho * rho - 0.25 * H.omega ** 2, 0.0))
        floor = float(np.exp(-delta * 2.0 * np.pi / H.omega))
    return _spectrum(lam, P, H, floor, "arnoldi", note, max_edge, complete)


#: orbit_spectrum's default min_ceiling: a stable verdict must hold for every multiplier up
#: to this modulus. A multiplier the window misses lies just past its ceiling (where it is
#: found it is the farthest eigenvalue and sets the ceiling itself): e^3.04-3.07 against
#: ceilings e^2.64-2.90 at N_h = 40, e^4.68 against e^4.63 at N_h = 80 on rotor 67, whose
#: NFRC multipliers reach e^7.8; 80 eigenvalues reach e^8.4-8.9 there.
MIN_CEILING = float(np.exp(8.0))
#: the window is widened at most to this many Hill eigenvalues.
MAX_EIG = 160


def orbit_spectrum(residual, u: np.ndarray, omega: float, *, jacobian=None, n_eig: int = 40,
                   dense_below: int = 200, period_rtol: float = 1e-4,
                   min_ceiling: float = MIN_CEILING) -> tuple[FloquetSpectrum, int]:
    """Floquet multipliers of the HBM solution u at omega over its minimal period.

    residual: hbm.harmonic.residual.HarmonicBalanceResidual; u: scaled unknowns (n_u,).
    omega: the continuation parameter Omega, rad/s. jacobian: its HbmJacobian at (u, omega)
    when at hand. The solution's harmonics give its minimal period T / g (harmonic_period,
    relative threshold period_rtol: the symmetric orbits of a 2-lobe casing keep their odd
    harmonics at round-off, ~1e-8 of the even ones, whereas a symmetry-broken orbit has
    them at percents); Hill's problem is solved in that basis (half the size for g = 2),
    dense below dense_below unknowns, by shift-invert Arnoldi above. min_ceiling: when the
    Arnoldi spectrum finds no unstable multiplier but its window reaches only multipliers
    below this modulus (FloquetSpectrum.modulus_ceiling), n_eig is doubled (up to MAX_EIG)
    until it does or one is found; 1 turns this off (the stability monitor does, and widens
    from its neighbours instead). An Arnoldi spectrum without a verdict is retried the same
    way (widened_spectrum); check FloquetSpectrum.decided. Returns (spectrum, g).
    """
    from hbm.stability.hill import harmonic_period, restrict

    H = HillOperator.from_residual(residual, u, omega, jacobian)
    g = harmonic_period(residual.to_coefficients(u), period_rtol)
    if H.basis.n_time % g:
        g = 1
    H = restrict(H, g)
    if H.size <= dense_below:
        return dense_spectrum(H), g
    return widened_spectrum(H, n_eig=n_eig, min_ceiling=min_ceiling), g


def widened_spectrum(H: HillOperator, n_eig: int = 40, min_ceiling: float = MIN_CEILING,
                     solver: HillSolver | None = None) -> FloquetSpectrum:
    """arnoldi_spectrum with n_eig eigenvalues, doubled (up to MAX_EIG, one factorisation for
    all) while the verdict is stable but its window ends below min_ceiling (see
    orbit_spectrum), or while there is no verdict (FloquetSpectrum.decided: a wider window is
    another Krylov run, which may converge where ARPACK stopped short, and reaches more
    family members, of which one may lie inside the band). The result can still be undecided."""
    solver = solver or HillSolver(H)
    spec = arnoldi_spectrum(H, n_eig=n_eig, solver=solver)
    while n_eig < MAX_EIG and (not spec.decided
                               or spec.stable and spec.modulus_ceiling < min_ceiling and not spec.note):
        n_eig = min(2 * n_eig, MAX_EIG)
        spec = arnoldi_spectrum(H, n_eig=n_eig, solver=solver)
    return spec
