"""The HBM Jacobian in its structured form, and its direct solve.

dH_r/dx~_r = Z_r + U G + F_v (N/m), on the unknowns x~_r ((2 N_h + 1) n_r, eq. 5 order):

- Z_r: the condensed dynamic stiffness, block diagonal per harmonic (27 x 27 complex blocks);
- U G: the normal-force part. On each node j in contact, the normal force on the AFT grid
  depends on one time signal g_j (RL: the radial displacement x_r; DLFT: the predicted
  Lagrangian, eps x_r - (Z_r x)_r), and it acts on the node's radial row and, through
  friction mu lam s, on its theta and z rows. So U (n_u x m) holds the AFT products
  T = F diag(w) F~ on those rows and G (m x n_u) picks g_j: m = n_contact (2 N_h + 1),
  at most 9 x 81 = 729 at N_h = 40, a third of n_u = 2187;
- F_v: the friction terms through the sliding direction s(v) (theta and z rows and
  columns), mu lam ds/dv ~ mu lam / (rho Omega). Small in norm (3e-4 to 3e-3 of J,
  Frobenius, at the rotor 67 primary resonance), but NOT next to the near-singular
  harmonic blocks of a resonance: the friction is most of their damping
  (||(J - F_v)^-1 F_v||_2 = 360 to 1400 there).

Solve (Woodbury form of the block elimination): with y = G x, x = Z^-1 (b - U y) and
(I + G Z^-1 U) y = G Z^-1 b, an m x m dense system; Z^-1 costs one 27 x 27 inverse per
harmonic. The preconditioner (ContactPreconditioner) solves Z' + U G exactly, Z' = Z_r plus
the time mean of F_v (harmonic-block-diagonal: the mean friction damping); GMRES on the
whole J does the rest (1.6 iterations on average with J's own preconditioner, 6 to 9 with
one 4 or more Newton solves old, over [1500, 2000] rad/s of RL at N_h = 40). Building it
costs ~12 ms at N_h = 40 (with friction the m x m LU in single precision, see
ContactPreconditioner) against 0.12-0.18 s for the LU of the dense 2187 x 2187 matrix. Nothing is
approximated: the result solves J x = b to the asked tolerance; a solve that does not
converge falls back to the dense LU.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.linalg as sla


def times_z_rows(T: np.ndarray, Z0: np.ndarray, P: np.ndarray, Q: np.ndarray, row: int) -> np.ndarray:
    """T @ (rows `row` of the dense Z over all harmonics), for T (q, n_c, n_c): (q, n_c, n_c n_r).

    Uses that Z is block diagonal per harmonic: O(q n_c^2 n_r) instead of O(q n_c^3 n_r).
    """
    nc, nr = T.shape[-1], Z0.shape[0]
    out = np.empty(T.shape[:2] + (nc, nr))
    out[:, :, 0, :] = T[:, :, 0, None] * Z0[row]
    Ta, Tb = T[:, :, 1::2, None], T[:, :, 2::2, None]  # (q, n_c, N_h, 1)
    Pr, Qr = P[:, row], Q[:, row]  # (N_h, n_r)
    out[:, :, 1::2, :] = Ta * Pr - Tb * Qr
    out[:, :, 2::2, :] = Ta * Qr + Tb * Pr
    return out.reshape(T.shape[:2] + (nc * nr,))


@dataclass(frozen=True)
class HbmJacobian:
    """dR/du of the scaled HBM residual, J = scale (Z_r + U G + F_v); see the module doc.

    op: hbm.harmonic.residual.CondensedOperator at omega (Z0, P, Q in N/m). scale: 1/k_ref,
    m/N (R and u are scaled so that J ~ 1). nodes: (n_t,) boundary nodes in contact.
    weights: (n_t, n_w, N_t) time weights on the AFT grid: [d lam/d g] (n_w = 1, no
    friction) or [d lam/d g, mu s_theta d lam/d g, mu s_z d lam/d g, mu lam ds_theta/dv_theta,
    mu lam ds_theta/dv_z, mu lam ds_z/dv_z] (n_w = 6): N/m per unit of g, and N s/m.
    basis: the hbm.harmonic.fourier.FourierBasis. sigma: (n_c,) Lanczos factors on the output rows.
    g_eps, g_z: g_j = g_eps x_r - g_z (Z_r x)_r: (1, 0) for RL, (epsilon, 1) for DLFT.
    The AFT products T = F diag(w) F~ are formed only when a preconditioner or the dense
    matrix needs them; `J @ v` goes through the FFT. Use `J @ v`, `np.asarray(J)` (dense,
    (n_u, n_u)), `J.factorize()` -> solve(b).
    """

    op: object
    scale: float
    nodes: np.ndarray
    weights: np.ndarray
    basis: object
    sigma: np.ndarray
    g_eps: float
    g_z: float

    @property
    def n_c(self) -> int:
        return 2 * self.op.P.shape[0] + 1

    @property
    def n_r(self) -> int:
        return self.op.Z0.shape[0]

    @property
    def shape(self) -> tuple[int, int]:
        n = self.n_c * self.n_r
        return (n, n)

    @property
    def friction(self) -> bool:
        return self.weights.shape[1] == 6

    # -- AFT products (on demand) -------------------------------------------------------------
    def _products(self, channels: slice) -> np.ndarray:
        T = self.basis.weighted_product(self.weights[:, channels])  # (n_t, n_ch, n_c, n_c)
        T *= self.sigma[:, None]  # Lanczos filter on the output coefficients
        return T

    @cached_property
    def T_normal(self) -> np.ndarray:
        """(n_t, n_q, n_c, n_c), N/m: the normal-force derivative onto the rows (r, theta, z)[:n_q]
        of each node (n_q = 3 with friction, 1 without), filter included."""
        return self._products(slice(0, 3 if self.friction else 1))

    @cached_property
    def T_slide(self) -> np.ndarray | None:
        """(n_t, 3, n_c, n_c) or None, N/m: the sliding-direction terms (theta-theta, theta-z,
        z-z) times omega D (velocity coefficients from displacement ones)."""
        if not self.friction:
            return None
        return self._products(slice(3, 6)) @ (self.op.omega * self.basis.derivative_matrix)

    @property
    def slide_mean(self) -> np.ndarray | None:
        """(n_t, 3), N s/m: time means of the sliding weights (tt, tz, zz)."""
        return self.weights[:, 3:].mean(axis=-1) if self.friction else None

    # -- products ---------------------------------------------------------------------------
    def _g(self, X: np.ndarray, ZX: np.ndarray) -> np.ndarray:
        R = 3 * self.nodes
        g = self.g_eps * X[:, R]
        if self.g_z:
            g = g - self.g_z * ZX[:, R]
        return g  # (n_c, n_t)

    def __matmul__(self, v: np.ndarray) -> np.ndarray:
        v = np.asarray(v, dtype=float)
        if v.ndim != 1:
            return np.column_stack([self @ c for c in v.reshape(v.shape[0], -1).T]).reshape(v.shape)
        op, nc, nr, b = self.op, self.n_c, self.n_r, self.basis
        X = v.reshape(nc, nr)
        Y = op.apply(X)
        if len(self.nodes):
            n3 = 3 * self.nodes
            nt = len(n3)
            g = self._g(X, Y)  # (n_c, n_t)
            w = self.weights  # (n_t, n_w, N_t)
            # signals as rows (last-axis FFTs): (k n_t, n_c) -> (k n_t, N_t)
            if self.friction:
                dX = self.op.omega * b.derivative(X)  # velocity coefficients
                sig = b.to_time(np.concatenate([g, dX[:, n3 + 1], dX[:, n3 + 2]], axis=1).T, axis=-1)
                gt, vt, vz = sig[:nt], sig[nt:2 * nt], sig[2 * nt:]  # (n_t, N_t): g, v_theta, v_z
                f = np.empty((3, nt, b.n_time))
                np.multiply(w[:, 0], gt, out=f[0])
                f[1] = w[:, 1] * gt + w[:, 3] * vt + w[:, 4] * vz
                f[2] = w[:, 2] * gt + w[:, 4] * vt + w[:, 5] * vz
            else:
                f = (w[:, 0] * b.to_time(g.T, axis=-1))[None]
            F = b.to_freq(f.reshape(-1, b.n_time), axis=-1) * self.sigma  # (n_q n_t, n_c)
            cols = (np.arange(f.shape[0])[:, None] + n3[None, :]).reshape(-1)  # q-major, as F's rows
            Y[:, cols] += F.T
        return self.scale * Y.reshape(-1)

    def toarray(self, out: np.ndarray | None = None) -> np.ndarray:
        """Dense J, (n_u, n_u), written into `out` when given."""
        op, nc, nr = self.op, self.n_c, self.n_r
        J = op.dense(out=out)
        J4 = J.reshape(nc, nr, nc, nr)
        J3 = J.reshape(nc, nr, nc * nr)
        for i, j in enumerate(self.nodes):
            r = 3 * int(j)
            Tn = self.T_normal[i]
            for q in range(Tn.shape[0]):
                J4[:, r + q, :, r] += self.g_eps * Tn[q]
            if self.g_z:
                contrib = times_z_rows(Tn, op.Z0, op.P, op.Q, r)
                for q in range(Tn.shape[0]):
                    J3[:, r + q, :] -= self.g_z * contrib[q]
            if self.T_slide is not None:
                Tt, Tz = r + 1, r + 2
                Ts = self.T_slide[i]
                J4[:, Tt, :, Tt] += Ts[0]
                J4[:, Tt, :, Tz] += Ts[1]
                J4[:, Tz, :, Tt] += Ts[1]
                J4[:, Tz, :, Tz] += Ts[2]
        J *= self.scale
        return J

    def __array__(self, dtype=None):
        J = self.toarray()
        return J if dtype is None else J.astype(dtype)

    # -- solve ------------------------------------------------------------------------------
    def preconditioner(self, single: bool | None = None) -> "ContactPreconditioner":
        """The direct solve of this J without its sliding fluctuations (see the module doc);
        single: its m x m LU in single precision (None: with friction only)."""
        return ContactPreconditioner(self, single)

    def factorize(self, rtol: float = 1e-10, max_krylov: int = 60, stats: dict | None = None,
                  preconditioner: "ContactPreconditioner | None" = None, forcing: float = 0.0,
                  atol: float = 0.0):
        """solve(b) for J x = b, b (n_u,) or (n_u, k).

        preconditioner: a ContactPreconditioner of an earlier, nearby J to reuse (it costs
        about as much as 12 GMRES iterations to build); None builds this J's own.
        rtol: ||J x - b|| / ||b|| asked of GMRES. stats: a dict whose counters "krylov",
        "preconditioners" and "dense_fallback" are incremented. If GMRES stalls with a reused
        preconditioner, this J's own is built; if it stalls with that too, the dense LU
        answers. Raises hbm.continuation.newton.SingularJacobian when Z_r or the reduced matrix is singular.
        forcing, atol: the bordered solve (solve.bordered) asks GMRES for the relative residual
        min(1e-3, max(rtol, forcing ||[R; P]||, atol / ||[R; P]||)) (an inexact Newton step):
        forcing keeps Newton's convergence fast far from the solution, atol (an absolute
        residual, the size Newton's own test can ignore) stops over-solving the last step;
        0, 0: rtol.
        """
        from hbm.harmonic.solver import gmres
        from hbm.continuation.newton import SingularJacobian
        stats = stats if stats is not None else {}
        holder = {"pre": preconditioner}
        if preconditioner is None:
            holder["pre"] = self.preconditioner()
            stats["preconditioners"] = stats.get("preconditioners", 0) + 1
        # this J's own preconditioner (built here or handed in) is its exact inverse without friction
        pre0 = holder["pre"]
        exact = pre0.source is self and not pre0.single and (not self.friction or not len(self.nodes))
        dense = {}

        def solve_one(b):
            pre = holder["pre"]
            x = pre(b)
            if exact:
                return x
            x, it, ok = gmres(self.__matmul__, pre, b, x, rtol, max_krylov)
            stats["krylov"] = stats.get("krylov", 0) + it
            stats["last_krylov"] = it
            if ok:
                return x
            if pre.source is not self:  # the reused preconditioner is too far off: build this J's
                holder["pre"] = pre = self.preconditioner()
                stats["preconditioners"] = stats.get("preconditioners", 0) + 1
                x, it, ok = gmres(self.__matmul__, pre, b, pre(b), rtol, max_krylov)
                stats["krylov"] = stats.get("krylov", 0) + it
                stats["last_krylov"] = it
                if ok:
                    return x
            stats["dense_fallback"] = stats.get("dense_fallback", 0) + 1  # never seen; stays exact
            if "lu" not in dense:
                dense["lu"] = sla.lu_factor(self.toarray(), check_finite=False)
            return sla.lu_solve(dense["lu"], b, check_finite=False)

        def solve(b):
            b = np.asarray(b, dtype=float)
            cols = b.reshape(b.shape[0], -1)
            out = np.column_stack([solve_one(cols[:, c]) for c in range(cols.shape[1])])
            if not np.all(np.isfinite(out)):
                raise SingularJacobian("structured solve: non-finite result")
            return out.reshape(b.shape)

        def bordered(r_omega, p, q, R, P):
            """[[J, r_omega], [p^T, q]] [dx; dw] = -[R; P] by one GMRES (instead of the two
            solves of the block elimination), preconditioned by the block elimination done
            with the preconditioner. Returns (dx, dw, tol), tol the relative residual asked
            of GMRES; raises SingularJacobian if GMRES stalls (the caller then falls back to
            the block elimination)."""
            pre = holder["pre"]
            c = pre(r_omega)
            den = q - p @ c
            if not (np.isfinite(den) and den != 0.0):
                raise SingularJacobian("bordered preconditioner: zero pivot")

            def prec(v):
                a = pre(v[:-1])
                dw = (v[-1] - p @ a) / den
                return np.append(a - c * dw, dw)

            def mv(v):
                return np.append(self @ v[:-1] + r_omega * v[-1], p @ v[:-1] + q * v[-1])

            rhs = -np.append(R, P)
            rn = float(np.linalg.norm(rhs))
            tol = min(1e-3, max(rtol, forcing * rn, atol / max(rn, 1e-300))) if (forcing > 0 or atol > 0) else rtol
            d, it, ok = gmres(mv, prec, rhs, prec(rhs), tol, max_krylov)
            stats["krylov"] = stats.get("krylov", 0) + it
            stats["last_krylov"] = it
            if not ok or not np.all(np.isfinite(d)):
                raise SingularJacobian(f"bordered GMRES: no convergence in {it} iterations")
            return d[:-1], float(d[-1]), tol

        solve.preconditioner = holder
        solve.bordered = bordered
        return solve


class ContactPreconditioner:
    """Direct solve of J0 = scale (Z_r' + U G), J without the fluctuating sliding terms.

    Z_r' is Z_r plus the time-mean sliding terms (harmonic-block-diagonal, the friction
    damping). Woodbury form: with y = G x, (I + G Z'^-1 U) y = G Z'^-1 b, an m x m dense
    LU (m = n_contact (2 N_h + 1)), and x = Z'^-1 (b - U y); U acts node by node, Z'^-1
    harmonic by harmonic, so nothing of size n_u x m is formed. __call__(b): b (n_u,) -> x.
    source: the HbmJacobian it was built from. single: the LU in single precision (None:
    when J has friction, i.e. when the preconditioner is not J's exact inverse).
    """

    def __init__(self, J: HbmJacobian, single: bool | None = None):
        from hbm.continuation.newton import SingularJacobian
        self.source = J
        op, nc, nr = J.op, J.n_c, J.n_r
        Zc = op.P + 1j * op.Q
        nodes = np.asarray(J.nodes, dtype=int)
        if J.friction and len(nodes):
            # the sliding terms with their time-mean weights are harmonic-block-diagonal
            # (i k omega W_mean on the theta, z dof): the friction damping that regularises
            # Z_r near a resonance (without it GMRES needs ~100 iterations there)
            Zc = Zc.copy()
            k = np.arange(1, Zc.shape[0] + 1)
            sk = J.sigma[1::2] * k * op.omega  # Lanczos factors of the output rows
            for (wtt, wtz, wzz), j in zip(J.slide_mean, nodes):
                t, z = 3 * j + 1, 3 * j + 2
                Zc[:, t, t] += 1j * sk * wtt
                Zc[:, t, z] += 1j * sk * wtz
                Zc[:, z, t] += 1j * sk * wtz
                Zc[:, z, z] += 1j * sk * wzz
        try:
            self.Z0i = np.linalg.inv(op.Z0)
            self.Zi = np.linalg.inv(Zc) if op.P.shape[0] else np.zeros((0, nr, nr), complex)
        except np.linalg.LinAlgError as exc:
            raise SingularJacobian(f"Z_r singular: {exc}") from exc
        nt = len(nodes)
        self.m = m = nt * nc
        self.R = R = 3 * nodes
        self.nc, self.nr, self.scale, self.g_eps, self.g_z = nc, nr, J.scale, J.g_eps, J.g_z
        self.T = T = J.T_normal  # (n_t, n_q, n_c, n_c)
        # the m x m LU in single precision (see below); nothing to round without contact
        self.single = bool(m) and (bool(J.friction) if single is None else bool(single))
        if not m:
            return
        nq = T.shape[1]
        self.cols = cols = (R[:, None] + np.arange(nq)).reshape(-1)
        # S = I + g_eps (Z'^-1 U)[R rows] - g_z U[R rows], laid out (o, coefficient, i, c): row
        # node o, column node i. (Z'^-1 U)[R rows] per harmonic: only the n_q dof of node i
        # carry U's column block i, so Y[k, i, o, c] = sum_q Z'^-1_k[R_o, (i, q)] X_k[i, q, c]
        # (a batch of (n_t x n_q) @ (n_q x n_c) products), X_k the complex harmonic-k rows of T.
        # With friction the preconditioner only steers GMRES (which checks the true
        # residual in double precision), so S and its LU are single precision by default:
        # half the memory traffic of the m x m triangular solves, the largest cost of a
        # GMRES iteration. Without friction it is J's exact inverse and stays in double.
        Xc = (T[:, :, 1::2, :] - 1j * T[:, :, 2::2, :]).transpose(2, 0, 1, 3)  # (N_h, i, q, c)
        Zs = self.Zi[:, R][:, :, cols].reshape(-1, nt, nt, nq).transpose(0, 2, 1, 3)  # (N_h, i, o, q)
        Y = Zs @ Xc  # (N_h, i, o, c)
        Z0s = self.Z0i[np.ix_(R, cols)].reshape(nt, nt, nq).transpose(1, 0, 2)  # (i, o, q)
        Y0 = Z0s @ T[:, :, 0, :]  # (i, o, c)
        S = np.empty((nt, nc, nt, nc), dtype=np.float32 if self.single else float)
        S[:, 0] = Y0.transpose(1, 0, 2)
        S[:, 1::2] = Y.real.transpose(2, 0, 1, 3)
        S[:, 2::2] = Y.imag.transpose(2, 0, 1, 3)
        S[:, 2::2] *= -1.0
        if J.g_eps != 1.0:
            S *= J.g_eps
        if J.g_z:
            idx = np.arange(nt)
            S[idx, :, idx, :] -= J.g_z * T[:, 0]
        S = S.reshape(m, m)
        S[np.diag_indices(m)] += 1.0
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", sla.LinAlgWarning)
            self.lu = sla.lu_factor(S, check_finite=False, overwrite_a=True)
        if not np.all(np.isfinite(self.lu[0])) or np.any(np.diag(self.lu[0]) == 0.0):
            raise SingularJacobian("reduced contact matrix: zero pivot")

    def _zinv(self, B: np.ndarray) -> np.ndarray:
        """Z'^-1 B for coefficients B (n_c, n_r)."""
        out = np.empty_like(B)
        out[0] = self.Z0i @ B[0]
        Y = (self.Zi @ (B[1::2] - 1j * B[2::2])[..., None])[..., 0]
        out[1::2], out[2::2] = Y.real, -Y.imag
        return out

    def __call__(self, b: np.ndarray) -> np.ndarray:
        B = np.asarray(b, dtype=float).reshape(self.nc, self.nr) / self.scale
        zb = self._zinv(B)
        if not self.m:
            return zb.reshape(-1)
        rhs = self.g_eps * zb[:, self.R]
        if self.g_z:
            rhs = rhs - self.g_z * B[:, self.R]
        rhs = rhs.T.reshape(-1)
        y = sla.lu_solve(self.lu, rhs.astype(np.float32) if self.single else rhs, check_finite=False)
        y = y.astype(float).reshape(len(self.R), self.nc)
        Uy = np.zeros_like(B)
        Uy[:, self.cols] = (self.T @ y[:, None, :, None])[..., 0].reshape(len(self.cols), self.nc).T
        return (zb - self._zinv(Uy)).reshape(-1)
