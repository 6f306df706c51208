"""Direct solve of the HBM Jacobian without its fluctuating friction terms (Woodbury form).

J = scale (Z_r + U G + F_v) (hbm.harmonic.jacobian). With y = G x, x = Z^-1 (b - U y) and
(I + G Z^-1 U) y = G Z^-1 b, an m x m dense system; Z^-1 costs one 27 x 27 inverse per
harmonic. The preconditioner solves Z' + U G exactly, Z' = Z_r plus the time mean of F_v
(harmonic-block-diagonal: the mean friction damping); GMRES on the whole J does the rest
(1.6 iterations on average with J's own preconditioner, 6 to 9 with one 4 or more Newton
solves old, over [1500, 2000] rad/s of RL at N_h = 40). Building it costs ~12 ms at
N_h = 40 against 0.12-0.18 s for the LU of the dense 2187 x 2187 matrix.
"""
from __future__ import annotations

import warnings

import numpy as np
import scipy.linalg as sla

from hbm.harmonic.jacobian import HbmJacobian
from hbm.linalg.errors import SingularMatrixError


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
            raise SingularMatrixError(f"Z_r singular: {exc}") from exc
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
            raise SingularMatrixError("reduced contact matrix: zero pivot")

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
