"""Hill's operator of an HBM solution: the linearised equation of motion for perturbations
y(t) = exp(lam t) p(t), p periodic, in the HBM's real Fourier basis.

With p(t) = P_0 + sum_k P_ak cos(k omega t) + P_bk sin(k omega t) (complex coefficients,
eq. 5 order) on ALL n ROM dof (the 3 n_b boundary dof and the modal ones: the linear part is
then a polynomial in lam, whereas the condensed Z_r(lam) is rational in it), d/dt acts on
the coefficients as lam + omega D (D: hbm.harmonic.fourier.FourierBasis.derivative_matrix), so

    H(lam) = L0 + lam L1 + lam^2 L2,
    linear part:  K + C (lam + omega D) + M (lam + omega D)^2,
    contact part: the HBM Jacobian's, with the velocity and Z terms given their lam too.

Contact part, from the structured HBM Jacobian (hbm.harmonic.jacobian.HbmJacobian) at the
solution: on each node j in contact the normal force depends on one signal
g_j = g_eps p_r - g_z (H_lin(lam) p)_r (RL: the radial displacement; DLFT: the predicted
Lagrangian eps p_r - (Z p)_r, with Z replaced by the Hill operator's linear part
H_lin(lam), the consistent linearisation of the DLFT law in the Floquet ansatz) and friction
on the sliding velocity v = (lam + omega D) p of the (theta, z) dof. The Lanczos factors of
the RL filter act on the force rows, as in the residual. At lam = 0, H(0) is the HBM
Jacobian (on all dof, unscaled): Hill's problem H(lam) p = 0 is the HBM Jacobian's
eigenproblem completed by the lam terms.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.linalg.lapack import dgetrs

from hbm.harmonic.condensation import CondensedModel
from hbm.harmonic.fourier import FourierBasis
from hbm.harmonic.jacobian import HbmJacobian
from hbm.stability import kernels


@dataclass(frozen=True, eq=False)
class HillOperator:
    """H(lam) = L0 + lam L1 + lam^2 L2 at one HBM solution, on all ROM dof (see module doc).

    K, M, C: ROM matrices (n, n), N/m, kg, N s/m. omega: fundamental angular frequency of the
    HBM basis, rad/s. basis: FourierBasis (N_h, N_t). nodes: (n_t,) boundary nodes in
    contact; weights: (n_t, n_w, N_t) the HbmJacobian's time weights (N/m per unit of g and
    N s/m, n_w = 1 or 6, see HbmJacobian). sigma: (2 N_h + 1,) filter on force rows.
    g_eps, g_z: g = g_eps x_r - g_z (Z x)_r. nl: indices of the boundary dof (the first
    3 n_b, node-major r, theta, z; default: all dof), on which the contact acts and on which
    `solver` condenses the others. Unknowns: coefficient arrays P (2 N_h + 1, n), m
    (complex), flattened row-major for the dense matrices ((2 N_h + 1) n,).
    """

    K: np.ndarray
    M: np.ndarray
    C: np.ndarray
    omega: float
    basis: FourierBasis
    nodes: np.ndarray
    weights: np.ndarray
    sigma: np.ndarray
    g_eps: float
    g_z: float
    nl: np.ndarray | None = None

    @classmethod
    def from_residual(cls, residual, u: np.ndarray, omega: float, jacobian=None) -> "HillOperator":
        """The operator of hbm.harmonic.residual.HarmonicBalanceResidual at the solution u
        (scaled unknowns, (n_u,)) and omega (rad/s); `jacobian`: its HbmJacobian at that point
        when already computed (else evaluated here)."""
        J = jacobian if jacobian is not None else residual(u, omega)[1]
        m = residual.model
        return cls(K=m.K, M=m.M, C=m.C, omega=float(J.op.omega) if hasattr(J.op, "omega") else float(omega),
                   basis=J.basis, nodes=np.asarray(J.nodes, dtype=int), weights=np.asarray(J.weights),
                   sigma=np.asarray(J.sigma), g_eps=float(J.g_eps), g_z=float(J.g_z), nl=np.asarray(m.nl))

    # -- sizes ------------------------------------------------------------------------------
    @property
    def n(self) -> int:
        return self.K.shape[0]

    @property
    def n_c(self) -> int:
        return self.basis.n_coeffs

    @property
    def size(self) -> int:
        return self.n_c * self.n

    @property
    def friction(self) -> bool:
        return self.weights.shape[1] == 6

    # -- products ---------------------------------------------------------------------------
    def apply(self, lam: complex, P: np.ndarray) -> np.ndarray:
        """H(lam) P for coefficients P (n_c, n) complex (or flat (n_c n,)), N; same shape."""
        Y0, Y1, Y2 = self.terms(P)
        return Y0 + lam * Y1 + lam * lam * Y2

    def terms(self, P: np.ndarray, which: tuple[int, ...] = (0, 1, 2)) -> tuple[np.ndarray, ...]:
        """(L_k P for k in which) for coefficients P (n_c, n) (or flat (n_c n,)); same shape each.

        The contact part goes through the AFT products T (`products`, small dense matrices
        per node and weight channel): at N_h <= ~60 cheaper than FFTs of the signals.
        """
        shape = np.shape(P)
        P = np.asarray(P).reshape(self.n_c, self.n)
        D = self.basis.derivative_matrix
        w = self.omega
        DP = D @ P
        lin = {0: lambda: P @ self.K.T + w * (DP @ self.C.T) + w * w * ((D @ DP) @ self.M.T),
               1: lambda: P @ self.C.T + 2.0 * w * (DP @ self.M.T), 2: lambda: P @ self.M.T}
        Y = {k: np.array(lin[k](), dtype=np.result_type(P, float)) for k in which}
        if len(self.nodes):
            r = 3 * self.nodes
            T = self.products  # (n_t, n_w, n_c, n_c), filter included
            for k in which:
                if self.g_z or k == 0:
                    g = -self.g_z * Y[k][:, r] if self.g_z else 0.0
                    if k == 0:
                        g = g + self.g_eps * P[:, r]
                    # force on rows (r, theta, z)[:n_q] of each node: T_q g
                    nq = 3 if self.friction else 1
                    F = np.einsum("tqij,jt->iqt", T[:, :nq], g)  # (n_c, n_q, n_t)
                    for q in range(nq):
                        Y[k][:, r + q] += F[:, q]
                if self.friction and k < 2:  # sliding velocity (lam + omega D) p: omega D into L0, identity into L1
                    V = w * DP if k == 0 else P
                    vt, vz = V[:, r + 1], V[:, r + 2]
                    Y[k][:, r + 1] += np.einsum("tij,jt->it", T[:, 3], vt) + np.einsum("tij,jt->it", T[:, 4], vz)
                    Y[k][:, r + 2] += np.einsum("tij,jt->it", T[:, 4], vt) + np.einsum("tij,jt->it", T[:, 5], vz)
        return tuple(Y[k].reshape(shape) for k in which)

    def tail(self, P1: np.ndarray, P2: np.ndarray) -> np.ndarray:
        """L1 P1 + L2 P2 for coefficients P1, P2 (n_c, n) (or flat (n_c n,)), N; P1's shape.

        The same sum as `terms(P1, (1,))` + `terms(P2, (2,))` in one pass (the contact's g is
        linear in the two): the product that shift-invert Arnoldi on the linearised pencil
        asks for at every step (hbm.stability.spectrum.arnoldi_spectrum). The contact's
        products are compiled (hbm.stability.kernels); the operator is real, so complex
        coefficients go through as two real arrays.
        """
        shape = np.shape(P1)
        P1 = np.asarray(P1).reshape(self.n_c, self.n)
        P2 = np.asarray(P2).reshape(self.n_c, self.n)
        if np.iscomplexobj(P1) or np.iscomplexobj(P2):
            Y = self._tail_real(P1.real, P2.real) + 1j * self._tail_real(P1.imag, P2.imag)
        else:
            Y = self._tail_real(P1, P2)
        return Y.reshape(shape)

    def _tail_real(self, P1: np.ndarray, P2: np.ndarray) -> np.ndarray:
        D, w = self.basis.derivative_matrix, self.omega
        Y = P1 @ self.C.T + (2.0 * w * (D @ P1) + P2) @ self.M.T
        if len(self.nodes):
            if self.g_z:
                self._add_normal(Y, -self.g_z * Y[:, 3 * self.nodes])
            if self.friction:  # sliding velocity: the identity part of (lam + omega D) p
                kernels.add_sliding(Y, np.ascontiguousarray(P1), self.products, self._radial_rows)
        return Y

    def _add_normal(self, Y: np.ndarray, g: np.ndarray) -> None:
        """Y[:, rows (r, theta, z)[:n_q] of each contact node] += T_q g, g (n_c, n_t); Y real
        (n_c, n), in place."""
        kernels.add_normal(Y, np.ascontiguousarray(g.T), self.products, self._radial_rows, 3 if self.friction else 1)

    @cached_property
    def _radial_rows(self) -> np.ndarray:
        """(n_t,) the radial dof of each contact node (node j's dof are 3 j .. 3 j + 2)."""
        return 3 * np.asarray(self.nodes, dtype=np.int64)

    # -- dense form ---------------------------------------------------------------------------
    @cached_property
    def products(self) -> np.ndarray:
        """T_c = sigma F diag(w_c) F~ for every weight channel, (n_t, n_w, n_c, n_c)."""
        return np.ascontiguousarray(self.basis.weighted_product(self.weights) * self.sigma[:, None])

    def dense(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(L0, L1, L2), each ((2 N_h + 1) n, (2 N_h + 1) n), real: H(lam) = L0 + lam L1 + lam^2 L2."""
        nc, n, w = self.n_c, self.n, self.omega
        D = self.basis.derivative_matrix
        I = np.eye(nc)
        L = [np.kron(I, self.K) + w * np.kron(D, self.C) + w * w * np.kron(D @ D, self.M),
             np.kron(I, self.C) + 2.0 * w * np.kron(D, self.M), np.kron(I, self.M)]
        if not len(self.nodes):
            return tuple(L)
        lin = [A.copy() for A in L]
        L4 = [A.reshape(nc, n, nc, n) for A in L]
        lin4 = [A.reshape(nc, n, nc, n) for A in lin]
        T = self.products
        for i, j in enumerate(self.nodes):
            r = 3 * int(j)
            for k in range(3):
                G = -self.g_z * lin4[k][:, r] if self.g_z else np.zeros((nc, nc, n))  # (n_c, n_c, n)
                if k == 0:
                    G = G.copy()
                    G[:, :, r] += self.g_eps * I
                for q in range(3 if self.friction else 1):
                    L4[k][:, r + q] += np.tensordot(T[i, q], G, axes=(1, 0))
            if self.friction:
                t, z = r + 1, r + 2
                for k, Dk in ((0, w * D), (1, I)):
                    L4[k][:, t, :, t] += T[i, 3] @ Dk
                    L4[k][:, t, :, z] += T[i, 4] @ Dk
                    L4[k][:, z, :, t] += T[i, 4] @ Dk
                    L4[k][:, z, :, z] += T[i, 5] @ Dk
        return tuple(L)


def harmonic_period(coeffs: np.ndarray, rtol: float = 1e-6) -> int:
    """g such that only harmonics that are multiples of g are present in coeffs.

    coeffs: (2 N_h + 1, ...) in eq. (5) order. A harmonic is present when its largest
    coefficient exceeds rtol times the largest non-constant one. The solution's minimal
    period is then T / g (T = 2 pi / omega); g = 1 when no harmonic is present.
    """
    c = np.asarray(coeffs)
    c = np.abs(c.reshape(c.shape[0], -1))
    amp = np.maximum(c[1::2].max(axis=1), c[2::2].max(axis=1))  # (N_h,)
    if amp.size == 0 or amp.max() == 0.0:
        return 1
    present = np.flatnonzero(amp > rtol * amp.max()) + 1
    return int(np.gcd.reduce(present))


def restrict(H: HillOperator, g: int) -> HillOperator:
    """The same operator on the basis of harmonics of g omega (the solution's minimal period
    T / g when its coefficients hold only multiples of g, see harmonic_period).

    The contact weights are then T / g periodic: their first N_t / g samples span one
    period of the new basis. The new basis keeps the harmonics k g <= N_h.
    """
    if g == 1:
        return H
    b = H.basis
    if b.n_time % g:
        raise ValueError(f"N_t = {b.n_time} is not a multiple of the period ratio {g}")
    nh = b.n_harmonics // g
    rows = np.concatenate([[0], np.stack([2 * g * np.arange(1, nh + 1) - 1, 2 * g * np.arange(1, nh + 1)], 1).reshape(-1)])
    return HillOperator(K=H.K, M=H.M, C=H.C, omega=g * H.omega, basis=FourierBasis(nh, b.n_time // g),
                        nodes=H.nodes, weights=H.weights[..., : b.n_time // g], sigma=H.sigma[rows],
                        g_eps=H.g_eps, g_z=H.g_z, nl=H.nl)


class HillSolver:
    """H(0)^-1 (the HBM Jacobian on all dof, unscaled) by a dense LU of its condensation on
    the dof of the nodes in contact and exact per-harmonic elimination of the others.

    The contact acts on the (r, theta, z) dof of the n_t nodes in contact only; every other
    dof (the modal ones and the boundary nodes out of contact) enters linearly, so it is
    eliminated exactly harmonic by harmonic (complex (n - 3 n_t)-square blocks). The
    condensed matrix ((2 N_h + 1) 3 n_t square) is the HbmJacobian's dense form on those
    dof, factorised once: (3 n_t / n_r)^3 of the LU on all n_r = 3 n_b boundary dof (0.47
    with 7 of the 9 rotor 67 nodes in contact), and each solve (two triangular solves, about
    0.26 ms at N_h = 20 with 7 nodes, memory-bound) (3 n_t / n_r)^2 of it. Shift-invert
    Arnoldi needs ~100 solves per analysis, accurate to round-off (GMRES solves would need
    ~10 times longer each for that accuracy). The eliminations around the LU solve are
    compiled (hbm.stability.kernels: 40 us a solve, where a dozen numpy calls took as long as
    the LU solve). Without contact the boundary dof H.nl are kept (the linear HBM's own form).
    __call__(b): b (n_c, n) or flat -> H(0)^-1 b, same shape.
    """

    def __init__(self, H: HillOperator):
        import scipy.linalg as sla

        self.H = H
        n = H.n
        nodes = np.asarray(H.nodes, dtype=int)
        if len(nodes):  # node j's dof are 3 j .. 3 j + 2 (HillOperator's layout)
            self.nl = (3 * nodes[:, None] + np.arange(3)).reshape(-1)
            cnodes = np.arange(len(nodes))  # their place in the condensed dof
        else:
            self.nl = np.arange(n) if H.nl is None else np.asarray(H.nl)
            cnodes = nodes
        self.nl = np.ascontiguousarray(self.nl, dtype=np.int64)
        self.li = np.setdiff1d(np.arange(n), self.nl).astype(np.int64)
        model = CondensedModel(H.K, H.M, H.C, self.nl, H.basis)
        op = model.operator(H.omega)
        J = HbmJacobian(op=op, scale=1.0, nodes=cnodes, weights=H.weights, basis=H.basis, sigma=H.sigma,
                        g_eps=H.g_eps, g_z=H.g_z)
        self.condensed = J  # the condensed matrix in structured form (products, preconditioners)
        self.lu = sla.lu_factor(J.toarray(), check_finite=False, overwrite_a=True)
        if not np.all(np.isfinite(self.lu[0])) or np.any(np.diag(self.lu[0]) == 0.0):
            from hbm.linalg.errors import SingularMatrixError
            raise SingularMatrixError("Hill operator at lam = 0: singular condensed matrix")
        li = self.li
        if len(li):
            w = H.omega
            k = np.arange(1, H.basis.n_harmonics + 1)[:, None, None] * w
            Kll, Mll, Cll = (A[np.ix_(li, li)] for A in (H.K, H.M, H.C))
            Zll = np.linalg.inv(Kll - k * k * Mll + 1j * k * Cll)  # (N_h, n_l, n_l)
            # real and imaginary parts for the compiled products (hbm.stability.kernels)
            self._Z0 = np.linalg.inv(Kll)
            self._ZR = np.ascontiguousarray(Zll.real)
            self._ZI = np.ascontiguousarray(Zll.imag)
            # the linear couplings between the two dof sets (the contact acts on nl only):
            # rows nl of the linear part applied to x on li, K, M, C blocks (n_l, n_r), and
            # back; per harmonic K - (k w)^2 M and k w C (hbm.stability.kernels.harmonic_blocks)
            self._to_nl = self._harmonic_blocks(li, self.nl, k)
            self._to_li = self._harmonic_blocks(self.nl, li, k)
            pos = np.full(n, -1)
            pos[self.nl] = np.arange(len(self.nl))
            self._r_nl = pos[3 * np.asarray(H.nodes, dtype=np.int64)]  # radial rows of the contact nodes in nl

    def _harmonic_blocks(self, cols: np.ndarray, rows: np.ndarray, kw: np.ndarray):
        """(A0, AK, AC): the blocks that carry x on dof `cols` into the linear part's rows
        `rows`: K[rows, cols] (p, m), and per harmonic (K - (k w)^2 M)[rows, cols] and
        (k w C)[rows, cols], (N_h, p, m)."""
        K, M, C = (np.ascontiguousarray(A[np.ix_(rows, cols)]) for A in (self.H.K, self.H.M, self.H.C))
        return K, np.ascontiguousarray(K - kw * kw * M), np.ascontiguousarray(kw * C)

    def __call__(self, b: np.ndarray) -> np.ndarray:
        """H(0)^-1 b. With y = Z_ll^-1 b_l on the linear dof: x_n = J_c^-1 (b_n - H_nl y)
        (J_c the condensed matrix, LU), x_l = y - Z_ll^-1 H_ln x_n. H_ln is linear (the
        contact acts on rows nl only); H_nl y adds, for DLFT, the contact through (Z y)_r.
        H(0) is real: complex b goes through as two real arrays."""
        shape = np.shape(b)
        B = np.asarray(b).reshape(self.H.n_c, self.H.n)
        if np.iscomplexobj(B):
            X = self._solve_real(B.real) + 1j * self._solve_real(B.imag)
        else:
            X = self._solve_real(B)
        return X.reshape(shape)

    def _solve_real(self, B: np.ndarray) -> np.ndarray:
        H, nl, li = self.H, self.nl, self.li
        nc, nr, n_l = H.n_c, len(nl), len(li)
        B = np.ascontiguousarray(B, dtype=float)
        X = np.empty(B.shape)
        if n_l:
            Y = np.empty((nc, n_l))
            rhs = np.empty((nc, nr))
            kernels.condensed_rhs(B, nl, li, self._Z0, self._ZR, self._ZI, *self._to_nl, H.products, self._r_nl,
                                  3 if H.friction else 1, float(H.g_z) if len(H.nodes) else 0.0,
                                  np.empty((nc, n_l)), Y, np.empty((nc, nr)), np.empty((len(H.nodes), nc)), rhs)
        else:
            rhs = B[:, nl]
        # LAPACK's getrs directly: scipy's lu_solve wrapper costs 4 % of a solve here
        xn, info = dgetrs(self.lu[0], self.lu[1], rhs.reshape(-1))
        if info:
            raise ValueError(f"getrs: illegal argument {-info}")
        xn = xn.reshape(nc, nr)
        if n_l:
            kernels.expand_solution(xn, Y, nl, li, self._Z0, self._ZR, self._ZI, *self._to_li,
                                    np.empty((nc, n_l)), np.empty((nc, n_l)), X)
        else:
            X[:, nl] = xn
        return X
