"""The HBM Jacobian in its structured form (products and dense form; solved in hbm.harmonic.solver).

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

The structure is what makes J cheap to solve without its dense LU: see
hbm.harmonic.preconditioner (Z_r and U G solved exactly by a Woodbury reduction) and
hbm.harmonic.solver (GMRES on the whole J).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np


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

    op: hbm.harmonic.condensation.CondensedOperator at omega (Z0, P, Q in N/m). scale: 1/k_ref,
    m/N (R and u are scaled so that J ~ 1). nodes: (n_t,) boundary nodes in contact.
    weights: (n_t, n_w, N_t) time weights on the AFT grid: [d lam/d g] (n_w = 1, no
    friction) or [d lam/d g, mu s_theta d lam/d g, mu s_z d lam/d g, mu lam ds_theta/dv_theta,
    mu lam ds_theta/dv_z, mu lam ds_z/dv_z] (n_w = 6): N/m per unit of g, and N s/m.
    basis: the hbm.harmonic.fourier.FourierBasis. sigma: (n_c,) Lanczos factors on the output rows.
    g_eps, g_z: g_j = g_eps x_r - g_z (Z_r x)_r: (1, 0) for RL, (epsilon, 1) for DLFT.
    The AFT products T = F diag(w) F~ are formed only when a preconditioner or the dense
    matrix needs them; `J @ v` goes through the FFT. Use `J @ v` or `np.asarray(J)` (dense,
    (n_u, n_u)).
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
        v = np.asarray(v)
        if np.iscomplexobj(v):  # J is real: its real and imaginary parts separately (eigenvectors)
            return (self @ v.real) + 1j * (self @ v.imag)
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

    def toarray(self) -> np.ndarray:
        """Dense J, (n_u, n_u)."""
        op, nc, nr = self.op, self.n_c, self.n_r
        J = op.dense()
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
