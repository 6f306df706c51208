"""Harmonic balance on the ROM, condensed on the nonlinear (boundary) dof, eqs. (1)-(17).

Unknowns. The multiharmonic vector of the 3 n_b boundary dof in eq. (5) order,
x~_r = [c_0, a_1, b_1, ..., a_Nh, b_Nh] (each block the n_r = 3 n_b dof, node-major r,
theta, z), scaled as u = alpha x~_r (alpha in 1/m, so that |u| ~ 1): this is the
normalisation alpha of eq. (1). The residual is H_r of eq. (8) divided by the force scale
k_ref / alpha (k_ref a stiffness scale of the condensed model, N/m), so that its Jacobian
is Z_r / k_ref + ... ~ O(1). Omega stays in rad/s (omega = Omega); the frequency scale
beta of eq. (1) only matters to the continuation's arc-length metric, which owns it.

Equation (internal-force form of eq. 1): M x'' + C x' + K x + f_nl(x, x', Omega) = f_ext,
f_nl = +lam on the radial dof (lam >= 0 compressive, see hbm.contact.normal) and +mu lam s on
(theta, z) (see hbm.contact.friction).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hbm.harmonic.fourier import FourierBasis
from hbm.contact.casing import casing_distance
from hbm.contact.normal import correct_dlft, regularised_penalty
from hbm.contact.friction import slide_direction
from hbm.harmonic.jacobian import HbmJacobian
from hbm.options import CasingOptions, ContactOptions, HbmOptions


@dataclass(frozen=True)
class HarmonicForcing:
    """External force f(t) = cos_amplitude cos(k omega t) + sin_amplitude sin(k omega t).

    cos_amplitude, sin_amplitude: (n,) on the ROM dof, N. harmonic: k >= 0 (k = 0: a
    static force cos_amplitude).
    """

    cos_amplitude: np.ndarray
    harmonic: int = 1
    sin_amplitude: np.ndarray | None = None


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

    def dense(self, derivative: bool = False, out: np.ndarray | None = None) -> np.ndarray:
        """Dense matrix in the unknown ordering (eq. 5), (n_c n_r, n_c n_r); written into
        `out` (same shape, overwritten) when given."""
        P, Q = (self.dP, self.dQ) if derivative else (self.P, self.Q)
        nh, nr = P.shape[0], self.Z0.shape[0]
        nc = 2 * nh + 1
        if out is None:
            Z = np.zeros((nc, nr, nc, nr))
        else:
            Z = out.reshape(nc, nr, nc, nr)
            Z.fill(0.0)
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
            fs = 0.0 if forcing.sin_amplitude is None else np.asarray(forcing.sin_amplitude)
            fc = np.asarray(forcing.cos_amplitude) - 1j * fs  # complex amplitude a - i b
        self._fc = fc
        self._cache: CondensedOperator | None = None
        self._split = None

    def _parts(self, A):
        return A[np.ix_(self.nl, self.nl)], A[np.ix_(self.nl, self.li)], A[np.ix_(self.li, self.nl)], A[np.ix_(self.li, self.li)]

    def complex_blocks(self, omega: float):
        """Complex Z_k = K - (k w)^2 M + i k w C and d/dw, (N_h, n, n), for k = 1 .. N_h."""
        k = np.arange(1, self.basis.n_harmonics + 1)[:, None, None]
        Z = self.K - (k * omega) ** 2 * self.M + 1j * k * omega * self.C
        dZ = -2.0 * k * k * omega * self.M + 1j * k * self.C
        return Z, dZ

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
            B = Znl @ np.linalg.inv(Zll)
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
        Z, _ = self.complex_blocks(omega)
        Zll, Zln = Z[:, li][:, :, li], Z[:, li][:, :, nl]
        Xn = xr[1::2] - 1j * xr[2::2]
        Fl = f[1::2, li] - 1j * f[2::2, li]
        Xl = np.linalg.solve(Zll, (Fl - np.einsum("kij,kj->ki", Zln, Xn))[..., None])[..., 0]
        out[1::2, li], out[2::2, li] = Xl.real, -Xl.imag
        return out


@dataclass(frozen=True)
class NonlinearSamples:
    """Nonlinear forces on the time grid, internal-force convention of eq. (1).

    force: (N_t, n_b, 3) (radial = lam, theta, z), N. lam: normal force, (N_t, n_b), N.
    displacement: boundary dof, (N_t, n_b, 3), m. velocity: (N_t, n_b, 3), m/s.
    gap: r - d, (N_t, n_b), m. active: contact indicator, (N_t, n_b).
    """

    force: np.ndarray
    lam: np.ndarray
    displacement: np.ndarray
    velocity: np.ndarray
    gap: np.ndarray
    active: np.ndarray
    aux: dict = field(default_factory=dict)


class HarmonicBalanceResidual:
    """residual(u, omega) -> (R, dR_du, dR_domega) for DLFT- or RL-HBM on the condensed ROM.

    u: scaled unknowns alpha x~_r, ((2 N_h + 1) n_r,), 1 (eq. 5 order). omega = Omega, rad/s.
    R: (n_u,), 1 (H_r alpha / k_ref). dR_du: dense (n_u, n_u), or an hbm.harmonic.jacobian.HbmJacobian when
    `structured` is set (same matrix; `J @ v`, `np.asarray(J)`, `J.factorize()`). dR_domega: (n_u,), s/rad.
    """

    def __init__(self, rom, casing: CasingOptions, contact: ContactOptions, hbm: HbmOptions,
                 method: str = "dlft", forcing: HarmonicForcing | None = None,
                 alpha: float | None = None, friction: bool = True, distance=None):
        if method not in ("dlft", "rl"):
            raise ValueError(f"unknown method '{method}'; known: dlft, rl")
        self.rom, self.casing, self.contact, self.options = rom, casing, contact, hbm
        self.method = method
        self.friction = friction and contact.mu > 0.0
        self.basis = FourierBasis(hbm.n_harmonics, hbm.n_time)
        self.n_b = rom.n_boundary
        self.n_r = 3 * self.n_b
        self.model = CondensedModel(rom.K, rom.M, rom.C, rom.nonlinear_dofs, self.basis, forcing)
        self.rho = np.asarray(rom.rho, dtype=float)
        self.theta = np.asarray(rom.theta, dtype=float)
        # distance(tau) -> (len(tau), n_b), m: the casing of eq. (28) unless another obstacle is given
        self._distance = distance or (lambda tau: casing_distance(tau, self.theta, casing))
        self.distance = self._distance(self.basis.tau)  # (N_t, n_b), m
        self.obstacle_scale = 1.0
        self.alpha = float(alpha if alpha is not None else 1.0 / max(casing.clearance, 1e-5))
        self.k_ref = float(np.mean(np.abs(np.diag(self.model.operator(0.0).Z0))))
        sig = self.basis.lanczos_sigma() if (method == "rl" and contact.lanczos) else np.ones(self.basis.n_coeffs)
        self.sigma = sig
        self.n_c = self.basis.n_coeffs
        self.size = self.n_c * self.n_r
        # jacobian_buffers = k > 0: dR_du is written into one of k preallocated arrays in
        # turn, so it stays valid only until k more Jacobians are evaluated. Saves, at
        # N_h = 40, the first-touch page faults of a fresh 38 MB array per Jacobian (~30 ms
        # of a 55 ms RL Jacobian). 0 (default): a new array every call.
        self.jacobian_buffers = 0
        self._jbufs: list[np.ndarray] = []
        self._jnext = 0
        # structured = True: dR_du comes back as an hbm.harmonic.jacobian.HbmJacobian (harmonic blocks
        # plus contact columns, solved without the dense LU); False: a dense ndarray.
        self.structured = False

    # -- scaling ---------------------------------------------------------------------------
    def to_coefficients(self, u: np.ndarray) -> np.ndarray:
        """Condensed harmonics x~_r, (2 N_h + 1, n_r), m, from u."""
        return np.asarray(u, dtype=float).reshape(self.n_c, self.n_r) / self.alpha

    def to_unknowns(self, xr: np.ndarray) -> np.ndarray:
        """u = alpha x~_r, ((2 N_h + 1) n_r,), from (2 N_h + 1, n_r) harmonics in m."""
        return (self.alpha * np.asarray(xr, dtype=float)).reshape(-1)

    # -- time domain -----------------------------------------------------------------------
    def samples(self, xr: np.ndarray, omega: float, basis: FourierBasis | None = None,
                op: CondensedOperator | None = None) -> NonlinearSamples:
        """Nonlinear forces on a time grid (the AFT grid unless another basis is given).

        xr: condensed harmonics, (2 N_h + 1, n_r), m (N_h of the problem).
        """
        b = basis or self.basis
        if b.n_harmonics != self.basis.n_harmonics:
            raise ValueError("basis must keep the problem's N_h")
        nb = self.n_b
        d = self.distance if b is self.basis else self._distance(b.tau)
        if self.obstacle_scale != 1.0:  # homotopy from a round casing (see set_obstacle_scale)
            d = d.max(axis=0) + self.obstacle_scale * (d - d.max(axis=0))
        x3 = xr.reshape(self.n_c, nb, 3)
        disp = b.to_time(x3)  # (N_t, n_b, 3)
        vel = omega * b.to_time(b.derivative(x3))
        gap = disp[..., 0] - d
        aux = {}
        if self.method == "dlft":
            op = op or self.model.operator(omega)
            rest = (op.force - op.apply(xr)).reshape(self.n_c, nb, 3)[..., 0]  # (f - Z x)_r
            lam, active = correct_dlft(b.to_time(rest) + self.contact.epsilon * gap)
            dlam = active.astype(float)
        else:
            lam, dlam = regularised_penalty(gap, self.contact.kappa, self.contact.gamma)
            active = gap > 0.0
        aux["dlam"] = dlam
        force = np.zeros(disp.shape)
        force[..., 0] = lam
        if self.friction:
            s = slide_direction(vel[..., 1], vel[..., 2], self.rho, omega)
            mu = self.contact.mu
            force[..., 1] = mu * lam * s.s_theta
            force[..., 2] = mu * lam * s.s_z
            aux["slide"] = s
        return NonlinearSamples(force=force, lam=lam, displacement=disp, velocity=vel, gap=gap,
                                active=active, aux=aux)

    def set_obstacle_scale(self, s: float) -> None:
        """Scale the obstacle's distortion: d_s = max_t d + s (d - max_t d), s in [0, 1].

        s = 0 is a round casing at the clearance (no contact for small motion), s = 1 the
        real one: a homotopy that brings the start point into contact gently.
        """
        self.obstacle_scale = float(s)

    # -- residual --------------------------------------------------------------------------
    def __call__(self, u: np.ndarray, omega: float, jacobian: bool = True):
        omega = float(omega)
        xr = self.to_coefficients(u)
        op = self.model.operator(omega)
        smp = self.samples(xr, omega, op=op)
        sig = self.sigma[:, None]
        fnl = sig * self.basis.to_freq(smp.force.reshape(-1, self.n_r))
        H = op.apply(xr) - op.force + fnl
        scale = self.alpha / self.k_ref
        R = scale * H.reshape(-1)
        if not jacobian:
            return R
        J = self._jacobian(xr, omega, op, smp)
        dH = op.apply(xr, derivative=True) - op.dforce + sig * self._dforce_domega(xr, omega, op, smp)
        return R, J, scale * dH.reshape(-1)

    def _dforce_domega(self, xr, omega, op, smp) -> np.ndarray:
        """Partial d f~_nl / d omega (before the sigma filter), (2 N_h + 1, n_r), N s/rad."""
        nb, b = self.n_b, self.basis
        dF = np.zeros((b.n_time, nb, 3))
        dlam = np.zeros((b.n_time, nb))
        if self.method == "dlft":
            drest = (op.dforce - op.apply(xr, derivative=True)).reshape(self.n_c, nb, 3)[..., 0]
            dlam = smp.aux["dlam"] * b.to_time(drest)
        dF[..., 0] = dlam
        if self.friction:
            s, mu, lam, v = smp.aux["slide"], self.contact.mu, smp.lam, smp.velocity
            # v = omega dx/dtau so dv/domega = v / omega; the sliding speed also has rho
            dvt = v[..., 1] / omega + self.rho
            dvz = v[..., 2] / omega
            dF[..., 1] = mu * (dlam * s.s_theta + lam * (s.ds_theta_dvtheta * dvt + s.ds_theta_dvz * dvz))
            dF[..., 2] = mu * (dlam * s.s_z + lam * (s.ds_theta_dvz * dvt + s.ds_z_dvz * dvz))
        return b.to_freq(dF.reshape(-1, self.n_r))

    def _jacobian(self, xr, omega, op, smp):
        """dR/du = (Z_r + d f~_nl / d x~_r) / k_ref: an HbmJacobian when self.structured, else
        its dense (n_u, n_u) array."""
        b = self.basis
        dlam = smp.aux["dlam"]  # (N_t, n_b)
        mu = self.contact.mu
        # nodes never in contact (DLFT) carry no nonlinear force and add nothing
        touching = np.flatnonzero(np.any(dlam != 0.0, axis=0) | np.any(smp.lam != 0.0, axis=0))
        if self.friction:
            s, lam = smp.aux["slide"], smp.lam[:, touching].T
            d = dlam[:, touching].T
            weights = np.stack([d, mu * d * s.s_theta[:, touching].T, mu * d * s.s_z[:, touching].T,
                                mu * lam * s.ds_theta_dvtheta[:, touching].T, mu * lam * s.ds_theta_dvz[:, touching].T,
                                mu * lam * s.ds_z_dvz[:, touching].T], axis=1)  # (n_t, 6, N_t)
        else:
            weights = dlam[:, touching].T[:, None, :]
        g = (self.contact.epsilon, 1.0) if self.method == "dlft" else (1.0, 0.0)
        J = HbmJacobian(op=op, scale=1.0 / self.k_ref, nodes=touching, weights=weights, basis=b,
                        sigma=self.sigma, g_eps=g[0], g_z=g[1])
        if self.structured:
            return J
        out = None
        if self.jacobian_buffers > 0:
            if len(self._jbufs) != self.jacobian_buffers:
                self._jbufs = [np.empty((self.size, self.size)) for _ in range(self.jacobian_buffers)]
            out = self._jbufs[self._jnext % self.jacobian_buffers]
            self._jnext += 1
        return J.toarray(out=out)

    # -- solutions -------------------------------------------------------------------------
    def linear_solution(self, omega: float) -> np.ndarray:
        """Contact-free solution u at omega (zero without forcing: the casing distortion is
        the only excitation in the rotor 67 scene), ((2 N_h + 1) n_r,)."""
        op = self.model.operator(float(omega))
        x = np.zeros((self.n_c, self.n_r))
        x[0] = np.linalg.solve(op.Z0, op.force[0])
        Zc = op.P + 1j * op.Q
        F = op.force[1::2] - 1j * op.force[2::2]
        X = np.linalg.solve(Zc, F[..., None])[..., 0]
        x[1::2], x[2::2] = X.real, -X.imag
        return self.to_unknowns(x)

    def expand_harmonics(self, u: np.ndarray, omega: float) -> np.ndarray:
        """Full ROM harmonics, (2 N_h + 1, n), m, eq. (5) order (linear dof recovered)."""
        return self.model.recover(self.to_coefficients(u), float(omega))

    def signals(self, u: np.ndarray, omega: float, n_time: int | None = None) -> dict:
        """Time signals over one period tau = Omega t in [0, 2 pi).

        Returns a dict: tau (N_t,), rad; t (N_t,), s; displacement (N_t, n), m, all ROM dof;
        force (N_t, n_b, 3), N, nonlinear force on the boundary dof (eq. 1 convention:
        radial = normal force lam >= 0 pushing inward, theta/z = friction mu lam s);
        lam (N_t, n_b), N; gap r - d (N_t, n_b), m; distance d (N_t, n_b), m.
        """
        b = self.basis if n_time is None else FourierBasis(self.basis.n_harmonics, int(n_time))
        xr = self.to_coefficients(u)
        smp = self.samples(xr, float(omega), basis=b)
        full = b.to_time(self.expand_harmonics(u, omega))
        return {"tau": b.tau, "t": b.tau / float(omega), "displacement": full, "force": smp.force,
                "lam": smp.lam, "gap": smp.gap, "distance": smp.displacement[..., 0] - smp.gap}

    def radial_amplitude(self, u: np.ndarray, node: int = 0, n_time: int | None = None) -> float:
        """Peak-to-peak radial displacement max - min over the period at one node, m."""
        b = self.basis if n_time is None else FourierBasis(self.basis.n_harmonics, int(n_time))
        r = b.to_time(self.to_coefficients(u)[:, 3 * node])
        return float(r.max() - r.min())


def build_residual(rom, casing: CasingOptions, contact: ContactOptions, hbm_options: HbmOptions,
                   method: str = "dlft", forcing: HarmonicForcing | None = None, **kw) -> HarmonicBalanceResidual:
    """The HBM residual callable residual(u, omega) -> (R, dR_du, dR_domega); see
    HarmonicBalanceResidual. rom: a RomModel (or anything with K, M, C, rho, theta,
    n_boundary, nonlinear_dofs)."""
    return HarmonicBalanceResidual(rom, casing, contact, hbm_options, method=method, forcing=forcing, **kw)


def expand_harmonics(residual: HarmonicBalanceResidual, u: np.ndarray, omega: float) -> np.ndarray:
    """Full 39-dof harmonics (2 N_h + 1, n), m, of a solution u at omega."""
    return residual.expand_harmonics(u, omega)
