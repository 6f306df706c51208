"""Explicit central-difference time integration of the ROM with exact unilateral contact.

Contact is enforced with the forward-increment Lagrange multiplier method of Carpenter,
Taylor and Katona (1991): the multipliers lam_n at t_n are chosen so that the radial
constraint r_j <= d_j(Omega t_{n+1}) holds exactly at t_{n+1}. Sliding Coulomb friction
(eqs. 29-30 of the reference paper) acts on the (theta, z) dof of contacting nodes with
magnitude mu lam_j, opposed to the relative velocity (v_theta + rho_j Omega, v_z).

Convention (same as hbm/contact.py and hbm/friction.py): lam >= 0 is the compressive normal
force, N; the force on the blade is -lam e_r - mu lam s with s the unit sliding direction.

The ROM is integrated in its M-orthonormal eigenbasis x = Phi q: with modal damping the
linear update is n decoupled scalar recurrences and the contact check needs only the n_b
radial rows of Phi, so a step without contact costs a few hundred flops.

Central differences with a centred velocity treat the (diagonal) modal damping implicitly:
(1 + a_k) q_{n+1} = (2 - w_k^2 dt^2) q_n - (1 - a_k) q_{n-1} + dt^2 p_n, a_k = xi_k w_k dt.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from hbm.options import CasingOptions

# Off-diagonal modal damping below this fraction of the diagonal is round-off of a modal C.
_MODAL_C_RTOL = 1e-9


@dataclass(frozen=True)
class ModalSystem:
    """A structure with n_b contact nodes (r, theta, z local dof, node-major) then other dof,
    in its undamped eigenbasis.

    omega: eigenfrequencies w_k, (n,), rad/s, ascending.
    phi: M-orthonormal mode matrix, x = phi q, (n, n), m per unit modal coordinate.
    phi_t_m: phi^T M, q = phi_t_m x, (n, n), kg per m of x times the unit of q.
    damping: phi^T C phi, (n, n), 1/s (diagonal 2 xi_k w_k for modal damping).
    rho: radius of each contact node, (n_b,), m. theta: angular shift of each node, (n_b,), rad.
    """

    omega: np.ndarray = field(metadata={"unit": "rad/s"})
    phi: np.ndarray = field(metadata={"unit": "m"})
    phi_t_m: np.ndarray = field(metadata={"unit": "kg"})
    damping: np.ndarray = field(metadata={"unit": "1/s"})
    rho: np.ndarray = field(metadata={"unit": "m"})
    theta: np.ndarray = field(metadata={"unit": "rad"})

    @property
    def n_boundary(self) -> int:
        return int(len(self.rho))

    @property
    def n_dof(self) -> int:
        return int(len(self.omega))

    @property
    def is_modally_damped(self) -> bool:
        """Whether phi^T C phi is diagonal (to round-off)."""
        off = self.damping - np.diag(np.diag(self.damping))
        return bool(np.abs(off).max(initial=0.0) <= _MODAL_C_RTOL * np.abs(np.diag(self.damping)).max(initial=0.0))


def modal_system(K: np.ndarray, M: np.ndarray, C: np.ndarray, rho: np.ndarray, theta: np.ndarray) -> ModalSystem:
    """Eigen-decompose (K, M) and project C.

    K: (n, n), N/m. M: (n, n), kg. C: (n, n), N s/m. rho, theta: (n_b,), m and rad, with
    3 n_b <= n: dof 3j, 3j+1, 3j+2 are the (r, theta, z) dof of contact node j.
    """
    import scipy.linalg

    K, M, C = (np.asarray(a, dtype=float) for a in (K, M, C))
    rho = np.atleast_1d(np.asarray(rho, dtype=float))
    theta = np.atleast_1d(np.asarray(theta, dtype=float))
    if 3 * len(rho) > K.shape[0] or len(theta) != len(rho):
        raise ValueError(f"{len(rho)} contact nodes need 3 dof each, model has {K.shape[0]} dof")
    w2, phi = scipy.linalg.eigh(0.5 * (K + K.T), 0.5 * (M + M.T))
    if w2.min() <= 0.0:
        raise ValueError(f"model must be positive definite (clamped); smallest w^2 = {w2.min():.3e} rad^2/s^2")
    phi_t_m = phi.T @ M
    return ModalSystem(omega=np.sqrt(w2), phi=phi, phi_t_m=phi_t_m, damping=phi.T @ C @ phi,
                       rho=rho, theta=theta)


def rom_modal_system(rom) -> ModalSystem:
    """ModalSystem of a rom.model.RomModel (K, M, C, rho, theta)."""
    return modal_system(rom.K, rom.M, rom.C, rom.rho, rom.theta)


def critical_time_step(system: ModalSystem) -> float:
    """Largest stable central-difference time step, s.

    Undamped: dt_crit = 2 / w_max. With modal damping treated implicitly through the centred
    velocity (this integrator), the amplification polynomial of mode k is
    (1 + a) z^2 - (2 - h^2) z + (1 - a), h = w dt, a = xi w dt >= 0; its Jury conditions
    reduce to h < 2 whatever a, so damping does not lower the limit: dt_crit = 2 / w_max.
    The forward-increment Lagrange multipliers do not lower it either (Carpenter et al. 1991).
    Non-modal damping is integrated with its off-diagonal part lagged (explicit); for that
    case the explicit-damping bound 2 / w (sqrt(1 + z^2) - z) is taken over all modes, with
    z_k = sum_l |(phi^T C phi)_kl| / (2 w_k) a Gershgorin equivalent ratio (conservative).
    """
    w = system.omega
    if system.is_modally_damped:
        return float(2.0 / w.max())
    z = np.abs(system.damping).sum(axis=1) / (2.0 * w)
    return float(np.min(2.0 / w * (np.sqrt(1.0 + z * z) - z)))


def check_time_step(system: ModalSystem, dt: float) -> None:
    """Raise ValueError when dt exceeds the central-difference stability limit."""
    dt_crit = critical_time_step(system)
    if not 0.0 < dt < dt_crit:
        raise ValueError(f"time step dt = {dt:.6e} s is not in (0, dt_crit = {dt_crit:.6e} s): central "
                         f"differences are unstable above 2 / w_max (w_max = {system.omega.max():.6e} rad/s)")


@dataclass(frozen=True)
class Recording:
    """What to record during a march (all step indices count from the initial state, step 0).

    start: first recorded step n0 (>= 1). stride: steps between samples s. n_samples: samples
    (sample i is step n0 + i s). dofs: dof whose displacement is recorded, (n_x,).
    force_nodes: contact nodes whose forces are recorded, (n_f,). section_stride: steps
    between Poincare sections (sections at n0 + k section_stride up to the last step; 0: none).
    lam_m denotes the multiplier computed at step m (it moves x_m to x_{m+1}). Force sample i
    is the block mean of lam_m over the s steps m = n0 + i s - s//2 .. n0 + i s + s - 1 - s//2,
    so that impulsive forces keep their impulse once downsampled (s = 1: lam at step n0 + i);
    multipliers at the last step (m = n_steps) are never computed and read 0.
    """

    start: int
    stride: int
    n_samples: int
    dofs: np.ndarray
    force_nodes: np.ndarray
    section_stride: int = 0

    def __post_init__(self):
        if self.start < 1 or self.stride < 1 or self.n_samples < 0 or self.section_stride < 0:
            raise ValueError(f"invalid recording: start {self.start}, stride {self.stride}, "
                             f"n_samples {self.n_samples}, section_stride {self.section_stride}")


@dataclass(frozen=True)
class March:
    """Result of one central-difference march.

    times: sample times, (n_samples,), s. displacement: recorded dof, (n_samples, n_x), m.
    normal_force: lam of the recorded nodes (block means), (n_samples, n_f), N.
    friction_force: friction on the blade, (theta, z) of the recorded nodes, (n_samples, n_f, 2), N.
    section_times: (n_sec,), s. sections: radial displacement of all contact nodes at the
    Poincare sections, (n_sec, n_b), m.
    radial_max, radial_min: extreme radial displacement of each node over steps >= start,
    (n_b,), m. max_penetration: max over all steps and nodes of r_j - d_j after the contact
    correction, m (<= round-off). min_multiplier: smallest multiplier of an active node, N
    (>= 0; +inf when no contact). contact_steps: steps with at least one active node.
    active_set_failures: steps whose active-set iteration hit its cap (should be 0).
    x_final, v_final: state at the last step, (n,), m and m/s. dt: the time step, s.
    """

    times: np.ndarray = field(metadata={"unit": "s"})
    displacement: np.ndarray = field(metadata={"unit": "m"})
    normal_force: np.ndarray = field(metadata={"unit": "N"})
    friction_force: np.ndarray = field(metadata={"unit": "N"})
    section_times: np.ndarray = field(metadata={"unit": "s"})
    sections: np.ndarray = field(metadata={"unit": "m"})
    radial_max: np.ndarray = field(metadata={"unit": "m"})
    radial_min: np.ndarray = field(metadata={"unit": "m"})
    max_penetration: float = field(metadata={"unit": "m"})
    min_multiplier: float = field(metadata={"unit": "N"})
    contact_steps: int = field(metadata={"unit": "1"})
    active_set_failures: int = field(metadata={"unit": "1"})
    x_final: np.ndarray = field(metadata={"unit": "m"})
    v_final: np.ndarray = field(metadata={"unit": "m/s"})
    dt: float = field(metadata={"unit": "s"})


def march(system: ModalSystem, casing: CasingOptions, mu: float, omega: float, x0: np.ndarray,
          v0: np.ndarray, dt: float, n_steps: int, recording: Recording) -> March:
    """Integrate n_steps central-difference steps of dt from (x0, v0) at t = 0.

    system: the structure. casing: rigid casing of eq. (28) (p = -c gives a flat wall at r = c).
    mu: friction coefficient, -. omega: rotation speed Omega, rad/s (casing angle tau = Omega t).
    x0, v0: initial displacement and velocity, (n,), m and m/s. dt: s (checked against the
    stability limit). Returns a March; raises ValueError on an unstable dt or bad recording.
    """
    check_time_step(system, dt)
    n, nb = system.n_dof, system.n_boundary
    x0 = np.asarray(x0, dtype=float).reshape(n)
    v0 = np.asarray(v0, dtype=float).reshape(n)
    w = system.omega
    cd = np.diag(system.damping).copy()
    a = 0.5 * cd * dt  # xi w dt
    c1 = (2.0 - (w * dt) ** 2) / (1.0 + a)
    c2 = (1.0 - a) / (1.0 + a)
    s = dt * dt / (1.0 + a)
    coff = system.damping - np.diag(cd)
    has_coff = not system.is_modally_damped
    phi = np.ascontiguousarray(system.phi)
    pr = np.ascontiguousarray(phi[0:3 * nb:3])      # radial rows (n_b, n)
    pt = np.ascontiguousarray(phi[1:3 * nb:3])      # theta rows
    pz = np.ascontiguousarray(phi[2:3 * nb:3])      # z rows
    # Contact compliance blocks: r_{n+1} = r_hat - (A_rr + mu A_rt diag(s_t) + mu A_rz diag(s_z)) lam
    prs = pr * s
    a_rr, a_rt, a_rz = prs @ pr.T, prs @ pt.T, prs @ pz.T
    # Start: q_{-1} from a second-order Taylor expansion with the free (contact-less) acceleration.
    q0 = system.phi_t_m @ x0
    qd0 = system.phi_t_m @ v0
    qdd0 = -w * w * q0 - system.damping @ qd0
    qm1 = q0 - dt * qd0 + 0.5 * dt * dt * qdd0

    rec = recording
    dofs = np.asarray(rec.dofs, dtype=np.int64).reshape(-1)
    fnodes = np.asarray(rec.force_nodes, dtype=np.int64).reshape(-1)
    rec_rows = np.ascontiguousarray(phi[dofs]) if len(dofs) else np.zeros((0, n))
    last = rec.start + (rec.n_samples - 1) * rec.stride
    if rec.n_samples and last > n_steps:
        raise ValueError(f"recording needs step {last} but the march has {n_steps} steps")
    n_sec = (n_steps - rec.start) // rec.section_stride + 1 if rec.section_stride else 0
    out_x = np.zeros((rec.n_samples, len(dofs)))
    out_f = np.zeros((rec.n_samples, len(fnodes), 3))
    out_sec = np.zeros((n_sec, nb))
    stats = np.zeros(4)
    counts = np.zeros(2, dtype=np.int64)
    rmax = np.full(nb, -np.inf)
    rmin = np.full(nb, np.inf)
    q_end = np.zeros(n)
    qm_end = np.zeros(n)
    _march_kernel(c1, c2, s, np.ascontiguousarray(coff), has_coff, _padded_columns(pr.T), pt, pz, a_rr, a_rt, a_rz,
                  system.rho.astype(float), system.theta.astype(float), float(casing.clearance),
                  float(casing.penetration), float(casing.width), int(casing.n_lobes), float(mu),
                  float(omega), float(dt), q0, qm1, int(n_steps), int(rec.start), int(rec.stride),
                  int(rec.n_samples), rec_rows, fnodes, int(rec.section_stride), out_x, out_f, out_sec,
                  rmax, rmin, stats, counts, q_end, qm_end)
    steps = rec.start + rec.stride * np.arange(rec.n_samples)
    sec_steps = rec.start + rec.section_stride * np.arange(n_sec)
    return March(times=steps * dt, displacement=out_x, normal_force=out_f[:, :, 0],
                 friction_force=out_f[:, :, 1:], section_times=sec_steps * dt, sections=out_sec,
                 radial_max=rmax, radial_min=rmin, max_penetration=float(stats[0]) if n_steps else -math.inf,
                 min_multiplier=float(stats[1]) if counts[0] else math.inf, contact_steps=int(counts[0]),
                 active_set_failures=int(counts[1]), x_final=phi @ q_end,
                 v_final=phi @ ((q_end - qm_end) / dt), dt=float(dt))


def _padded_columns(a: np.ndarray) -> np.ndarray:
    """a (n, nb) padded with zero columns to 12 when nb <= 12 (the kernel's fast path)."""
    n, nb = a.shape
    if nb > 12:
        return np.ascontiguousarray(a)
    out = np.zeros((n, 12))
    out[:, :nb] = a
    return out


# ----------------------------------------------------------------------------------------
# Compiled kernel
# ----------------------------------------------------------------------------------------
@njit(cache=True)
def _casing(tau, theta_j, c, p, w, n_lobes):
    """d_j(tau) of eq. (28), the same operations as hbm.contact.casing.casing_distance."""
    period = 2.0 * math.pi / n_lobes
    x = tau + theta_j
    phase = x - period * math.floor(x / period)
    if phase >= period:  # floor round-off at exact multiples
        phase -= period
    phi = phase - math.pi / n_lobes
    z = phi / w
    return c - (c + p) * math.exp(-(z * z))


@njit(cache=True)
def _solve_small(A, b, m):
    """Solve A[:m, :m] x = b[:m] in place by Gaussian elimination with partial pivoting."""
    for k in range(m):
        piv = k
        big = abs(A[k, k])
        for i in range(k + 1, m):
            if abs(A[i, k]) > big:
                big = abs(A[i, k])
                piv = i
        if piv != k:
            for j in range(m):
                tmp = A[k, j]
                A[k, j] = A[piv, j]
                A[piv, j] = tmp
            tmp = b[k]
            b[k] = b[piv]
            b[piv] = tmp
        for i in range(k + 1, m):
            f = A[i, k] / A[k, k]
            for j in range(k, m):
                A[i, j] -= f * A[k, j]
            b[i] -= f * b[k]
    for k in range(m - 1, -1, -1):
        acc = b[k]
        for j in range(k + 1, m):
            acc -= A[k, j] * b[j]
        b[k] = acc / A[k, k]


@njit(cache=True, fastmath={'reassoc', 'contract'})
def _march_kernel(c1, c2, s, coff, has_coff, prT, pt, pz, a_rr, a_rt, a_rz, rho, theta, cc, cp,
                  cw, n_lobes, mu, Om, dt, q0, qm1, n_steps, n0, stride, n_out, rec_rows, fnodes,
                  sec_stride, out_x, out_f, out_sec, rmax, rmin, stats, counts, q_end, qm_end):
    n = c1.shape[0]
    nb = a_rr.shape[0]
    nbp = prT.shape[1]  # padded to 12 columns when nb <= 12
    nx = rec_rows.shape[0]
    nf = fnodes.shape[0]
    q = q0.copy()
    qm = qm1.copy()
    qn = np.zeros(n)
    rh = np.zeros(nbp)
    d = np.zeros(nb)
    lam = np.zeros(nb)
    st = np.zeros(nb)
    sz = np.zeros(nb)
    active = np.zeros(nb, dtype=np.bool_)
    idx = np.zeros(nb, dtype=np.int64)
    Am = np.zeros((nb, nb))
    Afull = np.zeros((nb, nb))
    bm = np.zeros(nb)
    vel = np.zeros(n)
    half = stride // 2
    max_pen = -1e300
    min_lam = 1e300
    n_contact = 0
    n_fail = 0
    inv_stride = 1.0 / stride
    period = 2.0 * math.pi / n_lobes
    inv_period = 1.0 / period
    centre = math.pi / n_lobes
    cpp = cc + cp
    # block b of the forces covers steps sf + b stride .. sf + (b + 1) stride - 1, sf = n0 - half
    sf = n0 - half
    if sf >= 0:
        f_block = -1
        f_next = sf
    else:
        f_block = (-sf) // stride
        f_next = sf + (f_block + 1) * stride
    x_next = n0
    x_block = 0
    s_next = n0 if sec_stride > 0 else -1
    s_block = 0
    for it in range(n_steps):
        m1 = it + 1  # the step being computed
        tau = Om * (m1 * dt)
        # free prediction and its radial displacements (loop order keeps the 9 sums independent)
        for j in range(nb):
            rh[j] = 0.0
        if has_coff:
            for k in range(n):
                vel[k] = (q[k] - qm[k]) / dt
            for k in range(n):
                acc = 0.0
                for l in range(n):
                    acc += coff[k, l] * vel[l]
                v = c1[k] * q[k] - c2[k] * qm[k] - s[k] * acc
                qn[k] = v
                for j in range(nb):
                    rh[j] += prT[k, j] * v
        elif nbp == 12:
            # up to 12 contact nodes: scalar accumulators that LLVM keeps in (vector)
            # registers; an array accumulator would be reloaded for every mode (4-5x slower)
            r0 = r1 = r2 = r3 = r4 = r5 = r6 = r7 = r8 = r9 = r10 = r11 = 0.0
            for k in range(n):
                v = c1[k] * q[k] - c2[k] * qm[k]
                qn[k] = v
                p = prT[k]
                r0 += p[0] * v
                r1 += p[1] * v
                r2 += p[2] * v
                r3 += p[3] * v
                r4 += p[4] * v
                r5 += p[5] * v
                r6 += p[6] * v
                r7 += p[7] * v
                r8 += p[8] * v
                r9 += p[9] * v
                r10 += p[10] * v
                r11 += p[11] * v
            rh[0] = r0
            rh[1] = r1
            rh[2] = r2
            rh[3] = r3
            rh[4] = r4
            rh[5] = r5
            rh[6] = r6
            rh[7] = r7
            rh[8] = r8
            rh[9] = r9
            rh[10] = r10
            rh[11] = r11
        else:
            for k in range(n):
                v = c1[k] * q[k] - c2[k] * qm[k]
                qn[k] = v
                for j in range(nb):
                    rh[j] += prT[k, j] * v
        # casing of eq. (28); exp(-z^2) <= 1 / (1 + z^2) gives a cheap lower bound of d that
        # rules contact out without the exponential for most nodes most of the time
        any_pen = False
        for j in range(nb):
            x = tau + theta[j]
            z = (x - period * math.floor(x * inv_period) - centre) / cw
            z2 = z * z
            if rh[j] < cc - cpp / (1.0 + z2):
                d[j] = cc - cpp / (1.0 + z2)  # a lower bound: only used for the diagnostics
                active[j] = False
            else:
                d[j] = cc - cpp * math.exp(-z2)
                active[j] = rh[j] >= d[j]
                if active[j]:
                    any_pen = True
        if any_pen:
            n_contact += 1
            for j in range(nb):
                st[j] = 0.0
                sz[j] = 0.0
            # active-set iteration: lam_A >= 0 and no inactive node beyond the casing
            converged = False
            for _ in range(4 * nb + 4):
                m = 0
                for j in range(nb):
                    if active[j]:
                        idx[m] = j
                        m += 1
                        if st[j] == 0.0 and sz[j] == 0.0:
                            # unit sliding direction from the centred predicted velocity
                            vt = 0.0
                            vz = 0.0
                            for k in range(n):
                                dq = qn[k] - qm[k]
                                vt += pt[j, k] * dq
                                vz += pz[j, k] * dq
                            vt = vt / (2.0 * dt) + rho[j] * Om
                            vz = vz / (2.0 * dt)
                            nrm = math.sqrt(vt * vt + vz * vz)
                            if nrm > 1e-12:
                                st[j] = vt / nrm
                                sz[j] = vz / nrm
                            for i in range(nb):
                                Afull[i, j] = a_rr[i, j] + mu * (a_rt[i, j] * st[j] + a_rz[i, j] * sz[j])
                for a_ in range(m):
                    i = idx[a_]
                    for b_ in range(m):
                        Am[a_, b_] = Afull[i, idx[b_]]
                    bm[a_] = rh[i] - d[i]
                _solve_small(Am, bm, m)
                worst = -1
                wval = 0.0
                for a_ in range(m):
                    if bm[a_] < wval:
                        wval = bm[a_]
                        worst = idx[a_]
                if worst >= 0:  # drop the most negative multiplier and re-solve
                    active[worst] = False
                    continue
                for j in range(nb):
                    lam[j] = 0.0
                for a_ in range(m):
                    lam[idx[a_]] = bm[a_]
                worst = -1
                wval = 0.0
                for i in range(nb):
                    if not active[i]:
                        r_i = rh[i]
                        for b_ in range(m):
                            r_i -= Afull[i, idx[b_]] * bm[b_]
                        if r_i > d[i]:
                            # d[i] may be the cheap lower bound: get the exact casing
                            x = tau + theta[i]
                            z = (x - period * math.floor(x * inv_period) - centre) / cw
                            d[i] = cc - cpp * math.exp(-(z * z))
                        if r_i - d[i] > wval:
                            wval = r_i - d[i]
                            worst = i
                if worst >= 0:  # an inactive node is pushed beyond the casing: add it
                    active[worst] = True
                    continue
                converged = True
                break
            if not converged:
                n_fail += 1
            # apply the contact and friction forces: q_{n+1} = q_hat - s (phi^T g) lam
            for b_ in range(m):
                j = idx[b_]
                lj = lam[j]
                ft = mu * st[j] * lj
                fz = mu * sz[j] * lj
                for k in range(n):
                    qn[k] -= s[k] * (prT[k, j] * lj + pt[j, k] * ft + pz[j, k] * fz)
                if lj < min_lam:
                    min_lam = lj
            for i in range(nb):
                acc = rh[i]
                for b_ in range(m):
                    acc -= Afull[i, idx[b_]] * lam[idx[b_]]
                rh[i] = acc
        for j in range(nb):
            if rh[j] - d[j] > max_pen:
                max_pen = rh[j] - d[j]
        # record the forces lam_it (applied at step it) as block means; counters, not
        # divisions, locate the block (an integer division per step costs as much as a mode)
        if it == f_next:
            f_block += 1
            f_next += stride
        if any_pen and 0 <= f_block < n_out:
            for a_ in range(nf):
                j = fnodes[a_]
                if lam[j] != 0.0:
                    out_f[f_block, a_, 0] += lam[j] * inv_stride
                    out_f[f_block, a_, 1] -= mu * st[j] * lam[j] * inv_stride
                    out_f[f_block, a_, 2] -= mu * sz[j] * lam[j] * inv_stride
        if any_pen:
            for j in range(nb):
                lam[j] = 0.0
        # rotate the state
        tmp = qm
        qm = q
        q = qn
        qn = tmp
        # record the state at step m1
        if m1 >= n0:
            for j in range(nb):
                if rh[j] > rmax[j]:
                    rmax[j] = rh[j]
                if rh[j] < rmin[j]:
                    rmin[j] = rh[j]
            if m1 == x_next and x_block < n_out:
                for a_ in range(nx):
                    acc = 0.0
                    for k in range(n):
                        acc += rec_rows[a_, k] * q[k]
                    out_x[x_block, a_] = acc
                x_block += 1
                x_next += stride
            if m1 == s_next:
                for j in range(nb):
                    out_sec[s_block, j] = rh[j]
                s_block += 1
                s_next += sec_stride
    stats[0] = max_pen
    stats[1] = min_lam
    counts[0] = n_contact
    counts[1] = n_fail
    for k in range(n):
        q_end[k] = q[k]
        qm_end[k] = qm[k]
