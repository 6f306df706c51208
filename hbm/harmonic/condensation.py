"""Exact condensation of the ROM on its nonlinear (boundary) dof, per harmonic (eq. 8).

Z_k(omega) = K - (k omega)^2 M + i k omega C for harmonic k; the linear dof (the ROM's
fixed-interface modal coordinates) carry no nonlinear force, so they are eliminated per
harmonic: Z_r,k = Z_nn - Z_nl Z_ll^-1 Z_ln, exact for any omega where Z_ll,k is regular.
At an eigenfrequency of the fixed-interface system (k omega = omega_fi, undamped) Z_ll,k is
singular and Z_r,k has a pole; near one its inverse loses about eps cond(Z_ll,k) of relative
accuracy, so the condensation is refused there (SingularMatrixError) rather than returned
inaccurate.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hbm.harmonic.fourier import FourierBasis
from hbm.linalg.errors import SingularMatrixError

#: Largest eps cond_1(Z_ll,k) accepted: Z_r,k's relative error (measured on the coarse rotor 67
#: ROM without damping, against 60-digit arithmetic: 3e-10 at cond_1 = 8e7, 4e-7 at 8e10, 5e-5
#: at 8e12, 1e7 at the pole itself). 1e-6 refuses only within ~1e-9 (relative) of a pole.
MAX_POLE_ERROR = 1e-6


def linear_block_inverse(Zll: np.ndarray, omega: float) -> np.ndarray:
    """Z_ll,k^-1 for the harmonic blocks Zll, (N_h, n_l, n_l) complex (harmonic k = 1 .. N_h
    at fundamental omega, rad/s), or SingularMatrixError naming the harmonic whose block is
    singular or too ill-conditioned for MAX_POLE_ERROR (k omega at a fixed-interface
    eigenfrequency: a pole of the condensation)."""
    norm1 = lambda A: np.abs(A).sum(axis=-2).max(axis=-1)  # noqa: E731  batched 1-norm
    try:
        inv = np.linalg.inv(Zll)
        cond = norm1(Zll) * norm1(inv)
    except np.linalg.LinAlgError:
        inv, cond = None, np.full(len(Zll), np.inf)
        for k, A in enumerate(Zll):  # name the singular harmonic(s)
            try:
                cond[k] = norm1(A) * norm1(np.linalg.inv(A))
            except np.linalg.LinAlgError:
                pass
    bad = np.flatnonzero(~(np.finfo(float).eps * cond <= MAX_POLE_ERROR))
    if len(bad):
        k = int(bad[0]) + 1
        raise SingularMatrixError(
            f"condensation at omega={omega:.9g} rad/s: harmonic {k} (k omega = {k * omega:.9g} rad/s) sits on a "
            f"fixed-interface eigenfrequency, cond_1(Z_ll) = {cond[k - 1]:.3e} (Z_r's relative error would be "
            f"~{np.finfo(float).eps * cond[k - 1]:.1e} > {MAX_POLE_ERROR:g})")
    return inv


@dataclass(frozen=True)
class HarmonicForcing:
    """External force f(t) = cos_amplitude cos(k omega t) + sin_amplitude sin(k omega t).

    cos_amplitude, sin_amplitude: (n,) on the ROM dof, N. harmonic: k >= 0 (k = 0: a
    static force cos_amplitude).
    """

    cos_amplitude: np.ndarray
    harmonic: int = 1
    sin_amplitude: np.ndarray | None = None

    def __post_init__(self):
        k = self.harmonic
        # an integral float (2.0) is that harmonic, as in FourierBasis; 1.5 or True is none
        if isinstance(k, (bool, np.bool_)) or not isinstance(k, (int, np.integer, float, np.floating)) \
                or not float(k).is_integer() or k < 0:
            raise ValueError(f"forcing harmonic must be an integer >= 0, got {k!r}")
        object.__setattr__(self, "harmonic", int(k))

    def complex_amplitude(self, n: int) -> np.ndarray:
        """a - i b, (n,) complex, N: the amplitude of f(t) = Re[(a - i b) exp(i k omega t)];
        ValueError naming the amplitude that is not one force per dof of the n-dof ROM."""
        for name in ("cos_amplitude", "sin_amplitude"):
            a = getattr(self, name)
            if a is not None and np.shape(a) != (n,):
                raise ValueError(f"forcing {name} must have shape ({n},), one force per ROM dof (N), "
                                 f"got {np.shape(a)}")
        fs = 0.0 if self.sin_amplitude is None else np.asarray(self.sin_amplitude, dtype=float)
        return np.asarray(self.cos_amplitude, dtype=float) - 1j * fs


@dataclass(frozen=True)
class CondensedOperator:
    """Z_r(omega) of eq. (8) per harmonic, with its omega-derivative and the condensed force.

    Z0: (n_r, n_r) static block, N/m. P, Q: (N_h, n_r, n_r) with Z_r,k = P_k + i Q_k in the
    complex form (cos/sin pair block [[P, Q], [-Q, P]]), N/m; dP, dQ: d/domega, N s/m.
    force: condensed external force coefficients, (2 N_h + 1, n_r), N; dforce: d/domega.
    """

    omega: float
    Z0: np.ndarray
    P: np.ndarray
    Q: np.ndarray
    dP: np.ndarray
    dQ: np.ndarray
    force: np.ndarray
    dforce: np.ndarray

    def apply(self, x: np.ndarray, derivative: bool = False) -> np.ndarray:
        """Z_r x (or dZ_r/domega x) for coefficients x, (2 N_h + 1, n_r, ...) -> same shape."""
        P, Q = (self.dP, self.dQ) if derivative else (self.P, self.Q)
        X = np.asarray(x, dtype=float)
        X3 = X.reshape(X.shape[0], X.shape[1], -1)  # batched matmul per harmonic (einsum was 2x slower)
        Y = np.empty(X3.shape)
        Y[0] = 0.0 if derivative else self.Z0 @ X3[0]
        a, b = X3[1::2], X3[2::2]
        Y[1::2] = P @ a + Q @ b
        Y[2::2] = P @ b - Q @ a
        return Y.reshape(X.shape)

    def dense(self, derivative: bool = False) -> np.ndarray:
        """Dense matrix in the unknown ordering (eq. 5), (n_c n_r, n_c n_r)."""
        P, Q = (self.dP, self.dQ) if derivative else (self.P, self.Q)
        nh, nr = P.shape[0], self.Z0.shape[0]
        nc = 2 * nh + 1
        Z = np.zeros((nc, nr, nc, nr))
        if not derivative:
            Z[0, :, 0, :] = self.Z0
        k = np.arange(nh)
        Z[2 * k + 1, :, 2 * k + 1, :] = P
        Z[2 * k + 2, :, 2 * k + 2, :] = P
        Z[2 * k + 1, :, 2 * k + 2, :] = Q
        Z[2 * k + 2, :, 2 * k + 1, :] = -Q
        return Z.reshape(nc * nr, nc * nr)


class CondensedModel:
    """Exact condensation of the ROM on its nonlinear dof, per harmonic (eq. 8).

    K, M, C: (n, n) ROM matrices, SI. nonlinear: indices of the n_r kept dof; the others
    (linear) are eliminated per harmonic and recovered with recover().
    """

    def __init__(self, K, M, C, nonlinear, basis: FourierBasis, forcing: HarmonicForcing | None = None):
        self.K, self.M, self.C = (np.asarray(a, dtype=float) for a in (K, M, C))
        n = self.K.shape[0]
        self.nl = np.asarray(nonlinear)
        self.li = np.setdiff1d(np.arange(n), self.nl)
        self.basis = basis
        self.forcing = forcing
        fc = np.zeros(n, dtype=complex)
        if forcing is not None:
            if not 0 <= forcing.harmonic <= basis.n_harmonics:
                raise ValueError(f"forcing harmonic {forcing.harmonic} outside 0..{basis.n_harmonics}")
            fc = forcing.complex_amplitude(n)
        self._fc = fc
        self._cache: CondensedOperator | None = None
        self._split = None

    def _parts(self, A):
        return A[np.ix_(self.nl, self.nl)], A[np.ix_(self.nl, self.li)], A[np.ix_(self.li, self.nl)], A[np.ix_(self.li, self.li)]

    def complex_blocks(self, omega: float) -> np.ndarray:
        """Complex Z_k = K - (k w)^2 M + i k w C, (N_h, n, n), N/m, for k = 1 .. N_h."""
        k = np.arange(1, self.basis.n_harmonics + 1)[:, None, None]
        return self.K - (k * omega) ** 2 * self.M + 1j * k * omega * self.C

    def operator(self, omega: float) -> CondensedOperator:
        """Condensed Z_r(omega), dZ_r/domega and force at omega (cached for the last omega)."""
        if self._cache is not None and self._cache.omega == omega:
            return self._cache
        nl, li, b = self.nl, self.li, self.basis
        nh, nr = b.n_harmonics, len(nl)
        if self._split is None:  # the K, M, C blocks and the static condensation, once
            for name, A in (("K", self.K), ("M", self.M), ("C", self.C)):
                if not np.allclose(A, A.T, rtol=1e-10, atol=1e-12 * np.abs(A).max()):
                    raise ValueError(f"ROM matrix {name} is not symmetric (the condensation assumes it)")
            self._split = [self._parts(A) for A in (self.K, self.M, self.C)]
            Kp = self._split[0]
            self._Z0 = Kp[0] - Kp[1] @ np.linalg.solve(Kp[3], Kp[2]) if len(li) else Kp[0].copy()
        (Knn, Knl, _, Kll), (Mnn, Mnl, _, Mll), (Cnn, Cnl, _, Cll) = self._split
        Z0 = self._Z0.copy()
        kk = np.arange(1, nh + 1)[:, None, None]
        kw = kk * omega
        kw2 = kw * kw
        # Z_k = K - (k w)^2 M + i k w C per block, dZ_k / dw = -2 k^2 w M + i k C; the
        # n-n block in real and imaginary parts (half the work of complex arrays)
        P, Q = Knn - kw2 * Mnn, kw * Cnn
        dP, dQ = (-2.0 * kk) * kw * Mnn, kk * Cnn
        force = np.zeros((2 * nh + 1, nr))
        dforce = np.zeros((2 * nh + 1, nr))
        if len(li):
            # K, M, C symmetric: Z_ln = Z_nl^T and Z_ll^-1 is symmetric, so with
            # B = Z_nl Z_ll^-1 (n_l = 12 modal dof: one small inverse per harmonic)
            # Z_r = Z_nn - B Z_nl^T and dZ_r = dZ_nn - E - E^T, E = (dZ_nl - B dZ_ll / 2) B^T
            Zll = Kll - kw2 * Mll + 1j * kw * Cll
            Znl = Knl - kw2 * Mnl + 1j * kw * Cnl
            dll = -2.0 * kk * kw * Mll + 1j * kk * Cll
            dnl = -2.0 * kk * kw * Mnl + 1j * kk * Cnl
            B = Znl @ linear_block_inverse(Zll, omega)
            BZ = B @ Znl.transpose(0, 2, 1)
            P -= BZ.real
            Q -= BZ.imag
            E = (dnl - 0.5 * (B @ dll)) @ B.transpose(0, 2, 1)
            E += E.transpose(0, 2, 1)
            dP -= E.real
            dQ -= E.imag
        f = self.forcing
        if f is not None:
            fn, fl = self._fc[nl], self._fc[li]
            if f.harmonic == 0:
                fr = fn.real - (Knl @ np.linalg.solve(Kll, fl.real) if len(li) else 0.0)
                force[0] = fr
            else:
                k = f.harmonic - 1
                if len(li):
                    y = np.linalg.solve(Zll[k], fl)
                    fr = fn - Znl[k] @ y
                    dfr = -dnl[k] @ y + Znl[k] @ np.linalg.solve(Zll[k], dll[k] @ y)
                else:
                    fr, dfr = fn, np.zeros_like(fn)
                force[2 * k + 1], force[2 * k + 2] = fr.real, -fr.imag
                dforce[2 * k + 1], dforce[2 * k + 2] = dfr.real, -dfr.imag
        op = CondensedOperator(omega=float(omega), Z0=Z0, P=P, Q=Q, dP=dP, dQ=dQ, force=force, dforce=dforce)
        self._cache = op
        return op

    def recover(self, xr: np.ndarray, omega: float) -> np.ndarray:
        """Full harmonics from the condensed ones: x_l = Z_ll^-1 (f_l - Z_ln x_n).

        xr: (2 N_h + 1, n_r), m. Returns (2 N_h + 1, n), m, eq. (5) order.
        """
        nl, li, nh = self.nl, self.li, self.basis.n_harmonics
        n = self.K.shape[0]
        out = np.zeros((2 * nh + 1, n))
        out[:, nl] = xr
        if not len(li):
            return out
        f = np.zeros((2 * nh + 1, n))
        if self.forcing is not None:
            k = self.forcing.harmonic
            if k == 0:
                f[0] = self._fc.real
            else:
                f[2 * k - 1], f[2 * k] = self._fc.real, -self._fc.imag
        Kll, Kln = self.K[np.ix_(li, li)], self.K[np.ix_(li, nl)]
        out[0, li] = np.linalg.solve(Kll, f[0, li] - Kln @ xr[0])
        Z = self.complex_blocks(omega)
        Zll, Zln = Z[:, li][:, :, li], Z[:, li][:, :, nl]
        Xn = xr[1::2] - 1j * xr[2::2]
        Fl = f[1::2, li] - 1j * f[2::2, li]
        Xl = (linear_block_inverse(Zll, omega) @ (Fl - np.einsum("kij,kj->ki", Zln, Xn))[..., None])[..., 0]
        out[1::2, li], out[2::2, li] = Xl.real, -Xl.imag
        return out
