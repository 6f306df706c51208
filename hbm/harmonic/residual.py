"""Harmonic balance on the ROM, condensed on the nonlinear (boundary) dof, eqs. (1)-(17).

Unknowns. The multiharmonic vector of the 3 n_b boundary dof in eq. (5) order,
x~_r = [c_0, a_1, b_1, ..., a_Nh, b_Nh] (each block the n_r = 3 n_b dof, node-major r,
theta, z), scaled as u = alpha x~_r (alpha in 1/m, so that |u| ~ 1): this is the
normalisation alpha of eq. (1). The residual is H_r of eq. (8) divided by the force scale
k_ref / alpha (k_ref a stiffness scale of the condensed model, N/m), so that its Jacobian
is Z_r / k_ref + ... ~ O(1). The continuation parameter is Omega in rad/s; the basis'
fundamental is omega = Omega / nu (HbmOptions.subharmonic = nu, 1 by default: harmonic k
is k Omega / nu, the casing angle Omega t is nu times the basis angle, and one basis
period holds nu revolutions). The frequency scale beta of eq. (1) only matters to the
continuation's arc-length metric, which owns it.

Equation (internal-force form of eq. 1): M x'' + C x' + K x + f_nl(x, x', Omega) = f_ext,
f_nl = +lam on the radial dof (lam >= 0 compressive, see hbm.contact.normal) and +mu lam s on
(theta, z) (see hbm.contact.friction).

Sense of rotation: the ROM's `rotation` s = +1 or -1. Node j sits at the absolute angle
s tau + theta_j (tau = Omega t), so it meets the casing d(s tau + theta_j) =
d(tau + s theta_j) (the lobe profile of eq. 28 is even about each lobe centre), and the
tip slides at (v_theta + s rho_j Omega, v_z).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from hbm.contact.casing import casing_distance
from hbm.contact.friction import rotation_sense, slide_direction
from hbm.contact.normal import correct_dlft, regularised_penalty
from hbm.harmonic.condensation import CondensedModel, CondensedOperator, HarmonicForcing
from hbm.harmonic.fourier import FourierBasis
from hbm.harmonic.jacobian import HbmJacobian
from hbm.options import CasingOptions, ContactOptions, HbmOptions


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


@dataclass(frozen=True, eq=False)
class CasingObstacle:
    """The casing of eq. (28) as a residual's obstacle: d(tau) -> (len(tau), n_b), m, at the
    casing angle tau = Omega t (rad) for nodes at the angles theta (signed by the sense of
    rotation), (n_b,), rad. A residual handed one as its distance (refined, or a residual
    built from another's _distance) knows it faces the casing, whose lobes' symmetry images()
    needs; any other callable is another obstacle."""

    theta: np.ndarray = field(metadata={"unit": "rad"})
    casing: CasingOptions

    def __call__(self, tau: np.ndarray) -> np.ndarray:
        return casing_distance(tau, self.theta, self.casing)


class HarmonicBalanceResidual:
    """residual(u, omega) -> (R, dR_du, dR_domega) for DLFT- or RL-HBM on the condensed ROM.

    u: scaled unknowns alpha x~_r, ((2 N_h + 1) n_r,), 1 (eq. 5 order), harmonics of
    Omega / nu (nu = hbm.subharmonic). omega: the rotation speed Omega, rad/s.
    R: (n_u,), 1 (H_r alpha / k_ref). dR_du: an hbm.harmonic.jacobian.HbmJacobian (the
    structured matrix: `J @ v`, `np.asarray(J)` for its dense (n_u, n_u) form). dR_domega:
    (n_u,), s/rad. `residual(u, omega, jacobian=False)` returns R alone.
    """

    def __init__(self, rom, casing: CasingOptions, contact: ContactOptions, hbm: HbmOptions,
                 method: str = "dlft", forcing: HarmonicForcing | None = None,
                 alpha: float | None = None, friction: bool = True, distance=None):
        if method not in ("dlft", "rl"):
            raise ValueError(f"unknown method '{method}'; known: dlft, rl")
        self.rom, self.casing, self.contact, self.options = rom, casing, contact, hbm
        self.method = method
        self.friction = friction and contact.mu > 0.0
        self.nu = int(getattr(hbm, "subharmonic", 1))
        self.basis = FourierBasis(hbm.n_harmonics, hbm.n_time)
        self.n_b = rom.n_boundary
        self.n_r = 3 * self.n_b
        self.forcing = forcing
        if forcing is not None and self.nu != 1:  # harmonic k of Omega is harmonic k nu of the basis
            if forcing.harmonic * self.nu > self.basis.n_harmonics:  # named as the user wrote it
                raise ValueError(f"forcing harmonic {forcing.harmonic} of Omega is harmonic "
                                 f"{forcing.harmonic * self.nu} of the basis Omega/{self.nu}, outside "
                                 f"0..{self.basis.n_harmonics}")
            forcing = replace(forcing, harmonic=forcing.harmonic * self.nu)
        self.model = CondensedModel(rom.K, rom.M, rom.C, rom.nonlinear_dofs, self.basis, forcing)
        self.rho = np.asarray(rom.rho, dtype=float)
        self.theta = np.asarray(rom.theta, dtype=float)
        self.rotation = rotation_sense(rom.rotation)
        # distance(tau) -> (len(tau), n_b), m, tau the casing angle Omega t: the casing of
        # eq. (28) unless another obstacle is given; d(s tau + theta_j) = d(tau + s theta_j)
        # since d is even about 0 (module docstring); sampled at tau = nu (basis angle)
        self._distance = distance or CasingObstacle(self.rotation * self.theta, casing)
        # images(): the lobes of this casing repeat in time
        self._casing_obstacle = isinstance(self._distance, CasingObstacle) and self._distance.casing == casing
        self.distance = self._distance(self.nu * self.basis.tau)  # (N_t, n_b), m
        self.obstacle_scale = 1.0
        self.alpha = float(alpha if alpha is not None else 1.0 / max(casing.clearance, 1e-5))
        self.k_ref = float(np.mean(np.abs(np.diag(self.model.operator(0.0).Z0))))
        sig = self.basis.lanczos_sigma(self.nu) if (method == "rl" and contact.lanczos) else np.ones(self.basis.n_coeffs)
        self.sigma = sig
        self.n_c = self.basis.n_coeffs
        self.size = self.n_c * self.n_r

    def refined(self, factor: int = 2) -> "HarmonicBalanceResidual":
        """The same problem (law, filter, forcing, obstacle, scaling) with factor times the
        harmonics and AFT samples: to ask whether a solution is converged in N_h. Unknowns
        carry over by padding: to_unknowns of to_coefficients(u) with zero rows appended."""
        if int(factor) < 2:
            raise ValueError(f"factor must be an integer >= 2, got {factor!r}")
        opts = replace(self.options, n_harmonics=int(factor) * self.basis.n_harmonics,
                       n_time=int(factor) * self.basis.n_time)
        fine = HarmonicBalanceResidual(self.rom, self.casing, self.contact, opts, method=self.method,
                                       forcing=self.forcing, alpha=self.alpha, friction=self.friction,
                                       distance=self._distance)
        fine.set_obstacle_scale(self.obstacle_scale)
        return fine

    def fundamental(self, omega: float) -> float:
        """The basis' fundamental Omega / nu, rad/s, at rotation speed omega = Omega."""
        return float(omega) / self.nu

    # -- scaling ---------------------------------------------------------------------------
    def to_coefficients(self, u: np.ndarray) -> np.ndarray:
        """Condensed harmonics x~_r, (2 N_h + 1, n_r), m, from u."""
        return np.asarray(u, dtype=float).reshape(self.n_c, self.n_r) / self.alpha

    def to_unknowns(self, xr: np.ndarray) -> np.ndarray:
        """u = alpha x~_r, ((2 N_h + 1) n_r,), from (2 N_h + 1, n_r) harmonics in m."""
        return (self.alpha * np.asarray(xr, dtype=float)).reshape(-1)

    def images(self, u: np.ndarray) -> list[np.ndarray]:
        """The other solutions that the solution u implies, in the scaled unknowns ((n_u,) each):
        its orbit shifted in time by j / n_l of a revolution, j = 1 .. nu n_l - 1. The casing's
        n_l lobes repeat every 1 / n_l of a revolution, so these shifts leave the residual
        unchanged; harmonic k of the basis turns by the angle k 2 pi j / (nu n_l). A
        period-doubled orbit (nu = 2) and its shift by one revolution are one physical orbit
        with two sets of coefficients, as are an orbit without the casing's symmetry (odd
        harmonics of Omega) and its shift by half a revolution. [] with another obstacle than
        the casing, with a forcing (it fixes the time origin), or when the shifts are not
        whole AFT samples (the discrete residual would not be invariant)."""
        n = self.nu * int(self.casing.n_lobes)
        if not self._casing_obstacle or self.forcing is not None or n < 2 or self.basis.n_time % n:
            return []
        xr = self.to_coefficients(u)
        a, b = xr[1::2], xr[2::2]  # (N_h, n_r) cosine and sine rows (eq. 5 order)
        k = np.arange(1, self.basis.n_harmonics + 1)[:, None]
        out = []
        for j in range(1, n):
            c, s = np.cos(k * (2.0 * np.pi * j / n)), np.sin(k * (2.0 * np.pi * j / n))
            y = xr.copy()
            y[1::2], y[2::2] = c * a + s * b, c * b - s * a
            out.append(self.to_unknowns(y))
        return out

    # -- time domain -----------------------------------------------------------------------
    def samples(self, xr: np.ndarray, omega: float, basis: FourierBasis | None = None,
                op: CondensedOperator | None = None) -> NonlinearSamples:
        """Nonlinear forces on a time grid (the AFT grid unless another basis is given).

        xr: condensed harmonics, (2 N_h + 1, n_r), m (N_h of the problem). omega: Omega, rad/s.
        """
        b = basis or self.basis
        if b.n_harmonics != self.basis.n_harmonics:
            raise ValueError("basis must keep the problem's N_h")
        nb = self.n_b
        d = self.distance if b is self.basis else self._distance(self.nu * b.tau)
        if self.obstacle_scale != 1.0:  # homotopy from a round casing (see set_obstacle_scale)
            d = d.max(axis=0) + self.obstacle_scale * (d - d.max(axis=0))
        x3 = xr.reshape(self.n_c, nb, 3)
        disp = b.to_time(x3)  # (N_t, n_b, 3)
        vel = self.fundamental(omega) * b.to_time(b.derivative(x3))
        gap = disp[..., 0] - d
        aux = {}
        if self.method == "dlft":
            op = op or self.model.operator(self.fundamental(omega))
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
            s = slide_direction(vel[..., 1], vel[..., 2], self.rho, omega, self.rotation)
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
        op = self.model.operator(self.fundamental(omega))
        smp = self.samples(xr, omega, op=op)
        sig = self.sigma[:, None]
        fnl = sig * self.basis.to_freq(smp.force.reshape(-1, self.n_r))
        H = op.apply(xr) - op.force + fnl
        scale = self.alpha / self.k_ref
        R = scale * H.reshape(-1)
        if not jacobian:
            return R
        J = self._jacobian(xr, omega, op, smp)
        # Z and the external force depend on Omega through omega = Omega / nu
        dH = (op.apply(xr, derivative=True) - op.dforce) / self.nu + sig * self._dforce_domega(xr, omega, op, smp)
        return R, J, scale * dH.reshape(-1)

    def _dforce_domega(self, xr, omega, op, smp) -> np.ndarray:
        """Partial d f~_nl / d omega (before the sigma filter), (2 N_h + 1, n_r), N s/rad."""
        nb, b = self.n_b, self.basis
        dF = np.zeros((b.n_time, nb, 3))
        dlam = np.zeros((b.n_time, nb))
        if self.method == "dlft":
            drest = (op.dforce - op.apply(xr, derivative=True)).reshape(self.n_c, nb, 3)[..., 0] / self.nu
            dlam = smp.aux["dlam"] * b.to_time(drest)
        dF[..., 0] = dlam
        if self.friction:
            s, mu, lam, v = smp.aux["slide"], self.contact.mu, smp.lam, smp.velocity
            # v = omega dx/dtau so dv/domega = v / omega; the sliding speed also has s rho
            dvt = v[..., 1] / omega + self.rotation * self.rho
            dvz = v[..., 2] / omega
            dF[..., 1] = mu * (dlam * s.s_theta + lam * (s.ds_theta_dvtheta * dvt + s.ds_theta_dvz * dvz))
            dF[..., 2] = mu * (dlam * s.s_z + lam * (s.ds_theta_dvz * dvt + s.ds_z_dvz * dvz))
        return b.to_freq(dF.reshape(-1, self.n_r))

    def _jacobian(self, xr, omega, op, smp) -> HbmJacobian:
        """dR/du = (Z_r + d f~_nl / d x~_r) / k_ref in its structured form."""
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
        return HbmJacobian(op=op, scale=1.0 / self.k_ref, nodes=touching, weights=weights, basis=b,
                           sigma=self.sigma, g_eps=g[0], g_z=g[1])

    # -- solutions -------------------------------------------------------------------------
    def linear_solution(self, omega: float) -> np.ndarray:
        """Contact-free solution u at omega (zero without forcing: the casing distortion is
        the only excitation in the rotor 67 scene), ((2 N_h + 1) n_r,)."""
        op = self.model.operator(self.fundamental(omega))
        x = np.zeros((self.n_c, self.n_r))
        x[0] = np.linalg.solve(op.Z0, op.force[0])
        Zc = op.P + 1j * op.Q
        F = op.force[1::2] - 1j * op.force[2::2]
        X = np.linalg.solve(Zc, F[..., None])[..., 0]
        x[1::2], x[2::2] = X.real, -X.imag
        return self.to_unknowns(x)

    def expand_harmonics(self, u: np.ndarray, omega: float) -> np.ndarray:
        """Full ROM harmonics, (2 N_h + 1, n), m, eq. (5) order (linear dof recovered), in the
        basis of Omega / nu; omega: Omega, rad/s."""
        return self.model.recover(self.to_coefficients(u), self.fundamental(omega))

    def signals(self, u: np.ndarray, omega: float, n_time: int | None = None) -> dict:
        """Time signals over one period of the basis, tau = Omega t / nu in [0, 2 pi) (nu
        revolutions).

        Returns a dict: tau (N_t,), rad; t (N_t,), s; displacement (N_t, n), m, all ROM dof;
        force (N_t, n_b, 3), N, nonlinear force on the boundary dof (eq. 1 convention:
        radial = normal force lam >= 0 pushing inward, theta/z = friction mu lam s);
        lam (N_t, n_b), N; gap r - d (N_t, n_b), m; distance d (N_t, n_b), m.
        """
        b = self.basis if n_time is None else FourierBasis(self.basis.n_harmonics, int(n_time))
        xr = self.to_coefficients(u)
        smp = self.samples(xr, float(omega), basis=b)
        full = b.to_time(self.expand_harmonics(u, omega))
        return {"tau": b.tau, "t": b.tau / self.fundamental(omega), "displacement": full, "force": smp.force,
                "lam": smp.lam, "gap": smp.gap, "distance": smp.displacement[..., 0] - smp.gap}


def build_residual(rom, casing: CasingOptions, contact: ContactOptions, hbm_options: HbmOptions,
                   method: str = "dlft", forcing: HarmonicForcing | None = None, **kw) -> HarmonicBalanceResidual:
    """The HBM residual callable residual(u, omega) -> (R, dR_du, dR_domega); see
    HarmonicBalanceResidual. rom: a RomModel (or anything with K, M, C, rho, theta, rotation,
    n_boundary, nonlinear_dofs)."""
    return HarmonicBalanceResidual(rom, casing, contact, hbm_options, method=method, forcing=forcing, **kw)
