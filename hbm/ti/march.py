"""Explicit time integration of the ROM with exact unilateral contact.

Three schemes share one compiled loop (hbm.ti.kernel):

- "carpenter" (the reference): central differences and the forward-increment Lagrange
  multipliers of Carpenter, Taylor and Katona (1991). The multipliers lam_n at t_n are
  chosen so that the radial constraint r_j <= d_j(Omega t_{n+1}) holds exactly at t_{n+1};
  every ROM mode is integrated, so the step is bounded by the highest ROM frequency (the
  boundary dof's constraint modes) and an impact stops the boundary's mass in one step
  (restitution 0).
- "exponential": the same multipliers, with each mode's free motion over a step exact
  (recurrence): no stability limit, and no period error on the modes a step resolves
  coarsely. The step is then set by accuracy alone (benchmarks/README.md, *Time integration*).
- "massless": a massless boundary in the spirit of Monjaraz Tec, Gross and Krack (Computers &
  Structures 260, 2022, 106698; MacNeal's reduction, which gives a singular mass matrix).
  Here the parent model is the ROM itself: its eigenmodes up to a cut-off are integrated,
  the others are replaced by their static response (residual flexibility G of the boundary),
  which carries no mass. The boundary displacement is then x_b = phi_b q + G f, the contact a
  static projection at each step (r = Phi_r q - G lam <= d, lam >= 0, complementarity) and
  the step is set by the kept modes only. It is a different model: see massless_system.

Sliding Coulomb friction (eqs. 29-30 of the reference paper) acts on the (theta, z) dof of
contacting nodes with magnitude mu lam_j, opposed to the relative velocity
(v_theta + s rho_j Omega, v_z), s = +1 or -1 the sense of rotation (ModalSystem.rotation),
taken at the step's centred velocity after its own contact forces (a fixed point per step,
hbm.ti.kernel.run_steps): from the prediction's velocity alone the direction misses the
step's impulses, an O(dt) error that dominated the amplitude's dt-dependence on rotor 67.
Node j meets the casing at the absolute angle s Omega t + theta_j; eq. (28)'s casing is even
(its lobe centres pi / n_l + k 2 pi / n_l are symmetric about 0), so d(s tau + theta_j) =
d(tau + s theta_j), the angle the kernel evaluates (as hbm.harmonic.residual). Convention (as hbm.contact): lam >= 0 is the compressive normal
force, N; the force on the blade is -lam e_r - mu lam s with s the unit sliding direction.

The ROM is integrated in its M-orthonormal eigenbasis x = Phi q: with modal damping the
linear update is n decoupled scalar recurrences and the contact check needs only the n_b
radial rows of Phi, so a step without contact costs a few hundred flops. Central differences
with a centred velocity treat the (diagonal) modal damping implicitly:
(1 + a_k) q_{n+1} = (2 - w_k^2 dt^2) q_n - (1 - a_k) q_{n-1} + dt^2 p_n, a_k = xi_k w_k dt.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from threadpoolctl import threadpool_limits

from hbm.contact.casing import casing_distance
from hbm.contact.friction import rotation_sense
from hbm.options import TI_SCHEMES as SCHEMES, CasingOptions

# Off-diagonal modal damping below this fraction of the diagonal is round-off of a modal C.
_MODAL_C_RTOL = 1e-9


@dataclass(frozen=True)
class ModalSystem:
    """A structure with n_b contact nodes (r, theta, z local dof, node-major) then other dof,
    in (part of) its undamped eigenbasis: n dof, n_m <= n modes.

    omega: eigenfrequencies w_k, (n_m,), rad/s, ascending.
    phi: M-orthonormal mode matrix, x = phi q, (n, n_m), m per unit modal coordinate.
    phi_t_m: phi^T M, q = phi_t_m x, (n_m, n), kg per m of x times the unit of q.
    damping: phi^T C phi, (n_m, n_m), 1/s (diagonal 2 xi_k w_k for modal damping).
    rho: radius of each contact node, (n_b,), m. theta: angular shift of each node, (n_b,), rad.
    residual: None (every mode kept: the boundary carries mass), or the massless boundary's
        static response of every dof to unit forces on the 3 n_b boundary dof that the
        dropped modes carried, (n, 3 n_b), m/N: x = phi q + residual f_b.
    rotation: sense of rotation s = +1 or -1 (rom.model.RomModel.rotation): node j sits at
        the absolute angle s Omega t + theta_j and the tip slides at s rho_j Omega.
    """

    omega: np.ndarray = field(metadata={"unit": "rad/s"})
    phi: np.ndarray = field(metadata={"unit": "m"})
    phi_t_m: np.ndarray = field(metadata={"unit": "kg"})
    damping: np.ndarray = field(metadata={"unit": "1/s"})
    rho: np.ndarray = field(metadata={"unit": "m"})
    theta: np.ndarray = field(metadata={"unit": "rad"})
    residual: np.ndarray | None = field(default=None, metadata={"unit": "m/N"})
    rotation: int = field(default=1, metadata={"unit": "1"})

    def __post_init__(self):
        object.__setattr__(self, "rotation", rotation_sense(self.rotation))

    @property
    def n_boundary(self) -> int:
        return int(len(self.rho))

    @property
    def n_dof(self) -> int:
        return int(self.phi.shape[0])

    @property
    def n_modes(self) -> int:
        return int(len(self.omega))

    @property
    def is_massless(self) -> bool:
        return self.residual is not None

    @property
    def is_modally_damped(self) -> bool:
        """Whether phi^T C phi is diagonal (to round-off)."""
        off = self.damping - np.diag(np.diag(self.damping))
        return bool(np.abs(off).max(initial=0.0) <= _MODAL_C_RTOL * np.abs(np.diag(self.damping)).max(initial=0.0))

    def slowest_decay_time(self) -> float:
        """Largest free-decay time constant 1 / min |Re s| of the damped linear system, s
        (inf when a mode is undamped): how long a transient of the contact-free structure lives."""
        n = self.n_modes
        if self.is_modally_damped:
            rate = 0.5 * np.diag(self.damping)  # xi w: a damped mode decays as exp(-xi w t)
            over = rate > self.omega            # overdamped: the slow root w (xi - sqrt(xi^2 - 1))
            rate = np.where(over, rate - np.sqrt(np.maximum(rate * rate - self.omega ** 2, 0.0)), rate)
        else:
            a = np.block([[np.zeros((n, n)), np.eye(n)], [-np.diag(self.omega ** 2), -self.damping]])
            rate = -np.linalg.eigvals(a).real
        slowest = float(rate.min())
        return math.inf if slowest <= 0.0 else 1.0 / slowest


def modal_system(K: np.ndarray, M: np.ndarray, C: np.ndarray, rho: np.ndarray, theta: np.ndarray,
                 rotation: int = 1) -> ModalSystem:
    """Eigen-decompose (K, M) and project C.

    K: (n, n), N/m. M: (n, n), kg. C: (n, n), N s/m. rho, theta: (n_b,), m and rad, with
    3 n_b <= n: dof 3j, 3j+1, 3j+2 are the (r, theta, z) dof of contact node j.
    rotation: s = +1 or -1, the sense of rotation.
    """
    import scipy.linalg

    K, M, C = (np.asarray(a, dtype=float) for a in (K, M, C))
    rho = np.atleast_1d(np.asarray(rho, dtype=float))
    theta = np.atleast_1d(np.asarray(theta, dtype=float))
    if 3 * len(rho) > K.shape[0] or len(theta) != len(rho):
        raise ValueError(f"{len(rho)} contact nodes need 3 dof each, model has {K.shape[0]} dof")
    # one BLAS thread: a threaded eigh moves the modes by ~1e-13 with the thread count, and
    # the chaotic speeds of a sweep amplify that into another final state, so the same ROM
    # would give another sweep on a machine with more cores (or under taskset, or MPI)
    with threadpool_limits(limits=1, user_api="blas"):
        w2, phi = scipy.linalg.eigh(0.5 * (K + K.T), 0.5 * (M + M.T))
        if w2.min() <= 0.0:
            raise ValueError(f"model must be positive definite (clamped); smallest w^2 = {w2.min():.3e} rad^2/s^2")
        phi_t_m = phi.T @ M
        damping = phi.T @ C @ phi
    return ModalSystem(omega=np.sqrt(w2), phi=phi, phi_t_m=phi_t_m, damping=damping,
                       rho=rho, theta=theta, rotation=rotation)


def rom_modal_system(rom) -> ModalSystem:
    """ModalSystem of a rom.model.RomModel (K, M, C, rho, theta, rotation)."""
    return modal_system(rom.K, rom.M, rom.C, rom.rho, rom.theta, rom.rotation)


def massless_system(system: ModalSystem, cutoff: float) -> ModalSystem:
    """The massless-boundary model of a full ModalSystem: modes with w_k <= cutoff kept,
    the others replaced by their static response (MacNeal's residual flexibility).

    cutoff: rad/s. Returns a ModalSystem with n_m < n modes and residual
    R = sum_{w_k > cutoff} phi_k phi_k[b]^T / w_k^2, (n, 3 n_b), m/N (the dropped modes'
    share of K^-1 on the boundary columns). The model differs from the parent: the dropped
    modes' inertia is gone (their dynamics become static), so impacts are no longer
    absorbed by a boundary mass; with damping, the dropped modes' damping is gone too.
    """
    if system.is_massless:
        raise ValueError("the system is already massless")
    keep = system.omega <= cutoff
    if not keep.any():
        raise ValueError(f"no mode below the cut-off {cutoff:.4g} rad/s (lowest: {system.omega.min():.4g} rad/s)")
    if keep.all():
        raise ValueError(f"every mode is below the cut-off {cutoff:.4g} rad/s (highest {system.omega.max():.4g} "
                         f"rad/s): nothing would be massless")
    if not system.is_modally_damped:
        coupling = np.abs(system.damping[np.ix_(keep, ~keep)]).max()
        if coupling > _MODAL_C_RTOL * np.abs(np.diag(system.damping)).max():
            raise ValueError("non-modal damping couples the kept and the dropped modes: the massless "
                             "boundary model needs damping that does not couple them")
    hi = ~keep
    nb3 = 3 * system.n_boundary
    with threadpool_limits(limits=1, user_api="blas"):  # whatever the cores, as modal_system
        residual = (system.phi[:, hi] / system.omega[hi] ** 2) @ system.phi[:nb3, hi].T
    return ModalSystem(omega=system.omega[keep], phi=np.ascontiguousarray(system.phi[:, keep]),
                       phi_t_m=np.ascontiguousarray(system.phi_t_m[keep]),
                       damping=np.ascontiguousarray(system.damping[np.ix_(keep, keep)]),
                       rho=system.rho, theta=system.theta, residual=residual, rotation=system.rotation)


def scheme_system(system: ModalSystem, scheme: str, cutoff: float) -> ModalSystem:
    """The ModalSystem a scheme integrates: `system` itself ("carpenter", "exponential") or its
    massless model."""
    if scheme not in SCHEMES:
        raise ValueError(f"unknown time-integration scheme '{scheme}'; known: {', '.join(SCHEMES)}")
    if scheme == "massless":
        return system if system.is_massless else massless_system(system, cutoff)
    if system.is_massless:
        raise ValueError(f"the {scheme} scheme needs the full modal system, got a massless one")
    return system


def _boundary_blocks(system: ModalSystem):
    """Radial, theta and z rows of phi on the boundary, (n_b, n_m) each."""
    nb = system.n_boundary
    return (np.ascontiguousarray(system.phi[0:3 * nb:3]), np.ascontiguousarray(system.phi[1:3 * nb:3]),
            np.ascontiguousarray(system.phi[2:3 * nb:3]))


def _static_blocks(system: ModalSystem):
    """(G_rr, G_rt, G_rz): radial displacement per unit radial, theta and z boundary force of
    the massless boundary's residual flexibility, (n_b, n_b) each, m/N."""
    nb = system.n_boundary
    rb = system.residual[0:3 * nb:3]
    return (np.ascontiguousarray(rb[:, 0::3]), np.ascontiguousarray(rb[:, 1::3]),
            np.ascontiguousarray(rb[:, 2::3]))


def recurrence(system: ModalSystem, dt: float, exponential: bool = False):
    """(c1, c2, s), (n_m,) each: the two-step modal recurrence q_{m+1} = c1 q_m - c2 q_{m-1}
    + s f_m of each mode (w_k, modal damping 2 xi_k w_k), s^2/kg for s.

    Central differences (Carpenter's scheme, the massless one): c1 = (2 - h^2) / (1 + a),
    c2 = (1 - a) / (1 + a), s = dt^2 / (1 + a), h = w dt, a = xi w dt (centred damping);
    stable for h < 2. Exponential: the free motion of each mode over a step, exactly,
    c1 = 2 exp(-xi w dt) cos(w_d dt), c2 = exp(-2 xi w dt), w_d = w sqrt(1 - xi^2) (cosh past
    critical damping), stable at any dt; s = (1 - c1 + c2) / w^2 makes a constant force
    exact (the static response is a fixed point) and is >= 0, so the contact compliance
    Phi_r S Phi^T stays positive. Both tend to dt^2 for w dt -> 0. The exponential
    recurrence needs modal damping (ValueError otherwise): a coupled C has no per-mode
    propagator."""
    w = system.omega
    sig = 0.5 * np.diag(system.damping)  # xi w
    if not exponential:
        a = sig * dt
        return (2.0 - (w * dt) ** 2) / (1.0 + a), (1.0 - a) / (1.0 + a), dt * dt / (1.0 + a)
    if not system.is_modally_damped:
        raise ValueError("the exponential scheme integrates each mode on its own and needs modal damping "
                         "(phi^T C phi diagonal); this system's damping couples its modes: use scheme = carpenter")
    wd = np.sqrt((w * w - sig * sig).astype(complex))  # imaginary past critical damping: cos -> cosh
    decay = np.exp(-sig * dt)
    # a copy: .real is a strided view, and a non-contiguous c1 is another type to numba, so
    # the step loop would be compiled twice in a process that runs both schemes
    c1 = np.ascontiguousarray((2.0 * decay * np.cos(wd * dt)).real)
    # 1 - c1 + c2 without its cancellation at small w dt: (1 - e)^2 + 4 e sin^2(w_d dt / 2)
    gain = (np.expm1(-sig * dt) ** 2 + 4.0 * decay * np.sin(0.5 * wd * dt) ** 2).real
    return c1, decay * decay, gain / (w * w)


def step_compliance(system: ModalSystem, dt: float, exponential: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """(A_rr, A_rtheta), (n_b, n_b) each, m/N: the radial displacement of the contact nodes at
    the next step per unit radial and tangential force of the Carpenter scheme's multipliers,
    Phi_r S Phi_r^T and Phi_r S Phi_theta^T (~ dt^2 times the inverse mass's blocks; S of the
    central or exponential recurrence). With
    sliding friction the step's contact problem is r = r_hat - (A_rr + s mu A_rtheta) lam:
    its solution is unique only while that matrix is a P-matrix (rom.friction_lock.lock_table),
    past which the active set can cycle to its cap. Massless boundary: the step's compliance
    adds the static residual flexibility (not covered here: ValueError)."""
    if system.is_massless:
        raise ValueError("step_compliance is the Carpenter scheme's; a massless boundary adds its static flexibility")
    _, _, s = recurrence(system, dt, exponential)
    pr, pt, _ = _boundary_blocks(system)
    prs = pr * s
    return prs @ pr.T, prs @ pt.T


#: The exponential scheme has no stability limit, but its accuracy has one, set by the
#: highest modes (the boundary's constraint modes, which a contact impulse excites): a step
#: of at most half the period of the highest mode, pi / w_max, this fraction of the
#: central-difference limit 2 / w_max, samples every mode's response to a step's impulse at
#: least twice a period (beyond, a mode that turns by more than pi in a step answers the
#: impulse as a slower one would: the likely reason, not shown). Whole sweeps against
#: Carpenter at 5e-8 s (README, *Time integration*):
#: rotor 67's default ROM at 1e-6 s (0.93 of pi / w_max) keeps more classes than Carpenter at
#: 1e-7 s, at 2e-6 s (1.87) fewer, with amplitudes 4.7 % off. The ti stage warns above it.
EXPONENTIAL_STEP_FRACTION = 0.5 * math.pi


def critical_time_step(system: ModalSystem, mu: float = 0.0, exponential: bool = False) -> float:
    """Largest stable time step, s: inf for the exponential recurrence (each mode's free motion
    exact; the forward-increment multipliers only remove the penetration of the step's end).
    Central differences:

    Undamped: dt_crit = 2 / w_max. With modal damping treated implicitly through the centred
    velocity (this integrator), the amplification polynomial of mode k is
    (1 + a) z^2 - (2 - h^2) z + (1 - a), h = w dt, a = xi w dt >= 0; its Jury conditions
    reduce to h < 2 whatever a, so damping does not lower the limit: dt_crit = 2 / w_max.
    The forward-increment Lagrange multipliers do not lower it either (Carpenter et al. 1991).
    Non-modal damping is integrated with its off-diagonal part lagged (explicit); for that
    case the explicit-damping bound 2 / w (sqrt(1 + z^2) - z) is taken over all modes, with
    z_k = sum_l |(phi^T C phi)_kl| / (2 w_k) a Gershgorin equivalent ratio (conservative).

    Massless boundary: the static contact force lam = G_A^-1 (Phi_r q - d) acts on the modes
    one step later, like a spring: in contact the modes see the stiffness
    W^2 + (Phi_r + mu S_t Phi_t + mu S_z Phi_z)^T G_A^-1 Phi_r. Its spectral radius is largest
    with every node active (more constraints only stiffen, frictionless), and is taken over
    mu = 0 and sliding along +-theta with the given mu (the rotor's sliding direction) as w_max.
    """
    if exponential:
        if system.is_massless:
            raise ValueError("the exponential scheme integrates the full modal system; the massless one "
                             "keeps central differences")
        recurrence(system, 1.0, True)  # modal damping, or ValueError
        return math.inf
    w = system.omega
    if system.is_massless:
        pr, pt, _ = _boundary_blocks(system)
        g_rr, g_rt, _ = _static_blocks(system)
        radius = float(w.max() ** 2)
        for m_, sgn in ((0.0, 0.0), (mu, 1.0), (mu, -1.0)):
            a = g_rr + m_ * sgn * g_rt
            k = np.diag(w ** 2) + (pr + m_ * sgn * pt).T @ np.linalg.solve(a, pr)
            radius = max(radius, float(np.abs(np.linalg.eigvals(k)).max()))
        w = np.full_like(w, math.sqrt(radius))
    if system.is_modally_damped:
        return float(2.0 / w.max())
    z = np.abs(system.damping).sum(axis=1) / (2.0 * system.omega)
    return float(np.min(2.0 / w * (np.sqrt(1.0 + z * z) - z)))


def check_time_step(system: ModalSystem, dt: float, mu: float = 0.0, exponential: bool = False) -> None:
    """Raise ValueError when dt exceeds the scheme's stability limit (critical_time_step)."""
    dt_crit = critical_time_step(system, mu, exponential)
    if not 0.0 < dt < dt_crit:
        what = ("the kept modes and the static contact stiffness" if system.is_massless
                else f"w_max = {system.omega.max():.6e} rad/s")
        raise ValueError(f"time step dt = {dt:.6e} s is not in (0, dt_crit = {dt_crit:.6e} s): central "
                         f"differences are unstable above 2 / w_max ({what})"
                         + ("" if system.is_massless else "; scheme = exponential is stable at any dt"))


@dataclass(frozen=True)
class Recording:
    """What to record during a march (all step indices count from the initial state, step 0).

    start: first recorded step n0 (>= 1). stride: steps between samples s. n_samples: samples
    (sample i is step n0 + i s). dofs: dof whose displacement is recorded, (n_x,).
    force_nodes: contact nodes whose forces are recorded, (n_f,). section_stride: steps
    between Poincare sections (sections at n0 + k section_stride up to the last step; 0: none).
    extreme_stride: the radial extremes of every node are kept per block of this many steps
    from n0 (block b: steps n0 + b extreme_stride .. n0 + (b + 1) extreme_stride - 1; 0: one
    block for all steps >= n0).
    lam_m denotes the multiplier of step m: Carpenter's moves x_m to x_{m+1} (it is computed
    with step m + 1, so at the last step, m = n_steps, it is never computed and reads 0); the
    massless scheme's is the static projection at t_m (the last step's included). Force
    sample i is the block mean of lam_m over the s steps m = n0 + i s - s//2 .. n0 + i s + s -
    1 - s//2, so that impulsive forces keep their impulse once downsampled (s = 1: lam at step
    n0 + i). The steps of that block with lam_m > 0 are counted too (March.force_steps).
    """

    start: int
    stride: int
    n_samples: int
    dofs: np.ndarray
    force_nodes: np.ndarray
    section_stride: int = 0
    extreme_stride: int = 0

    def __post_init__(self):
        if (self.start < 1 or self.stride < 1 or self.n_samples < 0 or self.section_stride < 0
                or self.extreme_stride < 0):
            raise ValueError(f"invalid recording: start {self.start}, stride {self.stride}, "
                             f"n_samples {self.n_samples}, section_stride {self.section_stride}, "
                             f"extreme_stride {self.extreme_stride}")


@dataclass(frozen=True)
class March:
    """Result of one march (central differences or the exponential recurrence).

    times: sample times, (n_samples,), s. displacement: recorded dof, (n_samples, n_x), m.
    normal_force: lam of the recorded nodes (block means), (n_samples, n_f), N.
    friction_force: friction on the blade, (theta, z) of the recorded nodes, (n_samples, n_f, 2), N.
    force_steps: steps of each force sample's block (Recording) in which the node carried a
    normal force (lam_m > 0), (n_samples, n_f), - (whole numbers, 0 to the stride s): a block
    mean is > 0 as soon as one step of the block is in contact, force_steps / s is the share.
    section_times: (n_sec,), s. sections: radial displacement of all contact nodes at the
    Poincare sections, (n_sec, n_b), m.
    extremes: largest and smallest radial displacement of each node per block of
    extreme_stride steps >= start, (n_blocks, 2, n_b), m (-inf / +inf in blocks not reached).
    radial_max, radial_min: their extremes over all blocks, (n_b,), m. max_penetration: max
    of r_j - d_j after the contact correction over the steps and nodes whose d_j was
    evaluated, m (<= round-off once any node touched). On the casing table every node's is,
    at every step: without contact, the closest approach (< 0). On the law, nodes the cheap
    bound rules free are left out: -inf when no node ever came near. min_multiplier:
    smallest multiplier of an active node, N (>= 0; +inf when no contact). contact_steps:
    steps with at least one active node. active_set_failures: steps whose active-set
    iteration hit its cap (should be 0). explicit_direction_steps: contact steps whose
    friction took the prediction's sliding direction, where the step's own did not settle
    (a sliding reversal, a node dragged past its friction lock; hbm.ti.kernel.run_steps).
    n_steps: steps marched.
    x_final, v_final: state at the last step, (n,), m and m/s. dt: the time step, s.
    """

    times: np.ndarray = field(metadata={"unit": "s"})
    displacement: np.ndarray = field(metadata={"unit": "m"})
    normal_force: np.ndarray = field(metadata={"unit": "N"})
    friction_force: np.ndarray = field(metadata={"unit": "N"})
    section_times: np.ndarray = field(metadata={"unit": "s"})
    sections: np.ndarray = field(metadata={"unit": "m"})
    extremes: np.ndarray = field(metadata={"unit": "m"})
    max_penetration: float = field(metadata={"unit": "m"})
    min_multiplier: float = field(metadata={"unit": "N"})
    contact_steps: int = field(metadata={"unit": "1"})
    active_set_failures: int = field(metadata={"unit": "1"})
    n_steps: int = field(metadata={"unit": "1"})
    x_final: np.ndarray = field(metadata={"unit": "m"})
    v_final: np.ndarray = field(metadata={"unit": "m/s"})
    dt: float = field(metadata={"unit": "s"})
    force_steps: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)), metadata={"unit": "1"})
    explicit_direction_steps: int = field(default=0, metadata={"unit": "1"})


class Marcher:
    """A march that can be advanced in chunks (the sweep's early stop).

    Same arguments as `march`, with n_steps the most steps it may take: outputs are
    allocated for all of them; `advance` runs the compiled loop on, `result` reads the
    outputs so far (samples beyond the current step read 0). The scheme is the system's:
    massless when system.residual is set (see massless_system), Carpenter's otherwise, with
    the free modal motion by central differences or, exponential=True, exactly (recurrence).
    direction_tol: the change of the friction's unit sliding direction under which a step's
    direction is settled (default hbm.ti.kernel.DIRECTION_TOL; smaller for a reference).
    """

    def __init__(self, system: ModalSystem, casing: CasingOptions, mu: float, omega: float, x0: np.ndarray,
                 v0: np.ndarray, dt: float, n_steps: int, recording: Recording, exponential: bool = False,
                 direction_tol: float | None = None):
        from hbm.ti import kernel

        check_time_step(system, dt, mu, exponential)
        self._kernel = kernel
        self.system, self.dt, self.n_steps = system, float(dt), int(n_steps)
        self.recording = rec = recording
        n, nb = system.n_dof, system.n_boundary
        x0 = np.asarray(x0, dtype=float).reshape(n)
        v0 = np.asarray(v0, dtype=float).reshape(n)
        w = system.omega
        cd = np.diag(system.damping).copy()
        c1, c2, s = recurrence(system, dt, exponential)
        coff = np.ascontiguousarray(system.damping - np.diag(cd))
        pr, pt, pz = _boundary_blocks(system)
        # Compliance of the modal update: r_{n+1} = r_hat - (A_rr + mu A_rt diag(s_t) + mu A_rz diag(s_z)) lam
        prs = pr * s
        comp = (prs @ pr.T, prs @ pt.T, prs @ pz.T)
        if system.is_massless:
            comp = comp + _static_blocks(system)
        else:
            comp = comp + tuple(np.zeros((nb, nb)) for _ in range(3))
        # the theta and z displacements per force (the sliding direction's passes)
        pts, pzs = pt * s, pz * s
        comp = comp + (pts @ pr.T, pts @ pt.T, pts @ pz.T, pzs @ pr.T, pzs @ pt.T, pzs @ pz.T)
        self._lin = (c1, c2, s, coff)
        self._bnd = (_padded_columns(pr.T), pr, pt, pz)
        self._comp = comp
        # the sense enters as s rho (blade speed s rho Omega) and s theta (casing at tau + s theta_j)
        sense = float(system.rotation)
        self._geo = (sense * system.rho.astype(float), sense * system.theta.astype(float))
        self._cas = (float(casing.clearance), float(casing.penetration), float(casing.width), int(casing.n_lobes))
        self._profile = casing_profile(casing, self._geo[1], omega, dt)
        self._mu, self._omega = float(mu), float(omega)
        self._direction_tol = float(kernel.DIRECTION_TOL if direction_tol is None else direction_tol)
        self._has_coff = not system.is_modally_damped
        q0 = system.phi_t_m @ x0
        qd0 = system.phi_t_m @ v0
        if exponential:  # q_{-1}: each mode's free motion one step back, exactly
            sig = 0.5 * cd
            wd = np.sqrt((w * w - sig * sig).astype(complex))
            sinc = np.where(wd == 0, dt, np.sin(wd * dt) / np.where(wd == 0, 1.0, wd)).real
            qm1 = np.exp(sig * dt) * (q0 * np.cos(wd * dt).real - (qd0 + sig * q0) * sinc)
        else:  # q_{-1} from a second-order Taylor expansion with the free (contact-less) acceleration
            qdd0 = -w * w * q0 - system.damping @ qd0
            qm1 = q0 - dt * qd0 + 0.5 * dt * dt * qdd0
        nm = system.n_modes
        self._state = (q0.copy(), qm1, np.zeros(nb), np.zeros(nb), np.zeros(nb), np.zeros(nb, dtype=np.int64),
                       np.zeros(1, dtype=np.int64))
        self.step = 0
        dofs = np.asarray(rec.dofs, dtype=np.int64).reshape(-1)
        self._fnodes = np.asarray(rec.force_nodes, dtype=np.int64).reshape(-1)
        # the kernel indexes its node tables with these unchecked (a wrong one would read
        # or write past them); numpy would wrap a negative dof round to the last ones
        bad = dofs[(dofs < 0) | (dofs >= n)]
        if len(bad):
            raise ValueError(f"recording: dof {bad.tolist()} outside the {n} dof 0 .. {n - 1}")
        bad = self._fnodes[(self._fnodes < 0) | (self._fnodes >= nb)]
        if len(bad):
            raise ValueError(f"recording: force node {bad.tolist()} outside the {nb} contact nodes 0 .. {nb - 1}")
        self._dofs = dofs
        self._rec_rows = np.ascontiguousarray(system.phi[dofs]) if len(dofs) else np.zeros((0, nm))
        self._rec_frows = (np.ascontiguousarray(system.residual[dofs]) if system.is_massless and len(dofs)
                           else np.zeros((len(dofs), 3 * nb)))
        last = rec.start + (rec.n_samples - 1) * rec.stride
        if rec.n_samples and last > n_steps:
            raise ValueError(f"recording needs step {last} but the march has {n_steps} steps")
        n_sec = (n_steps - rec.start) // rec.section_stride + 1 if rec.section_stride and n_steps >= rec.start else 0
        n_ext = (max(n_steps - rec.start, 0) // rec.extreme_stride + 1) if rec.extreme_stride else 1
        self._rec = (int(rec.start), int(rec.stride), int(rec.n_samples), int(rec.section_stride),
                     int(rec.extreme_stride))
        self.out_x = np.zeros((rec.n_samples, len(dofs)))
        self.out_f = np.zeros((rec.n_samples, len(self._fnodes), 4))  # lam, friction (theta, z), steps
        self.out_sec = np.zeros((n_sec, nb))
        self.out_ext = np.empty((n_ext, 2, nb))
        self.out_ext[:, 0] = -np.inf
        self.out_ext[:, 1] = np.inf
        self._stats = np.array([-np.inf, np.inf])
        self._counts = np.zeros(3, dtype=np.int64)

    def advance(self, n_steps: int) -> "Marcher":
        """March min(n_steps, steps left) more steps."""
        n_steps = min(int(n_steps), self.n_steps - self.step)
        if n_steps > 0:
            par = (self._mu, self._omega, self.dt, self._has_coff, self.system.is_massless, self.step, n_steps,
                   self._direction_tol)
            self._kernel.run_steps(self._lin, self._bnd, self._comp, self._geo, self._cas, self._profile, par,
                                   self._state, self._rec, self._rec_rows, self._rec_frows, self._fnodes, self.out_x,
                                   self.out_f, self.out_sec, self.out_ext, self._stats, self._counts)
            self.step += n_steps
        return self

    @property
    def contact_steps(self) -> int:
        return int(self._counts[0])

    def result(self) -> March:
        """The march so far (step self.step)."""
        rec, dt, sys_ = self.recording, self.dt, self.system
        q, qm, lam, st, sz, idx, m_prev = self._state
        x_final = sys_.phi @ q
        if sys_.is_massless and m_prev[0] > 0:  # the static response to the last contact forces
            f = np.zeros(3 * sys_.n_boundary)
            j = idx[:m_prev[0]]
            f[3 * j] = -lam[j]
            f[3 * j + 1] = -self._mu * st[j] * lam[j]
            f[3 * j + 2] = -self._mu * sz[j] * lam[j]
            x_final = x_final + sys_.residual @ f
        steps = rec.start + rec.stride * np.arange(rec.n_samples)
        sec_steps = rec.start + rec.section_stride * np.arange(len(self.out_sec))
        return March(times=steps * dt, displacement=self.out_x, normal_force=self.out_f[:, :, 0],
                     friction_force=self.out_f[:, :, 1:3], section_times=sec_steps * dt, sections=self.out_sec,
                     extremes=self.out_ext, max_penetration=float(self._stats[0]),
                     min_multiplier=float(self._stats[1]), contact_steps=int(self._counts[0]),
                     active_set_failures=int(self._counts[1]), explicit_direction_steps=int(self._counts[2]),
                     n_steps=self.step, x_final=x_final,
                     v_final=sys_.phi @ ((q - qm) / dt), dt=float(dt), force_steps=self.out_f[:, :, 3])


def march(system: ModalSystem, casing: CasingOptions, mu: float, omega: float, x0: np.ndarray,
          v0: np.ndarray, dt: float, n_steps: int, recording: Recording, exponential: bool = False) -> March:
    """Integrate n_steps steps of dt from (x0, v0) at t = 0 (exponential: each mode's free
    motion exact over a step, see recurrence; else central differences).

    system: the structure (massless_system(...) for the massless-boundary scheme).
    casing: rigid casing of eq. (28) (p = -c gives a flat wall at r = c).
    mu: friction coefficient, -. omega: rotation speed Omega, rad/s (casing angle tau = Omega t).
    x0, v0: initial displacement and velocity, (n,), m and m/s (a massless system keeps their
    projection on its modes). dt: s (checked against the stability limit). Returns a March;
    raises ValueError on an unstable dt or bad recording.
    """
    return Marcher(system, casing, mu, omega, x0, v0, dt, n_steps, recording,
                   exponential).advance(n_steps).result()


def load_kernel(system: ModalSystem, casing: CasingOptions, mu: float, omega: float, dt: float,
                exponential: bool = False) -> None:
    """Compile the step loop for this march's argument types, or load it from numba's cache,
    by one throwaway step from rest, so that a caller who times its march does not time
    that: 15.5 s of CPU on a cold cache, 0.3 s from the cache (rotor 67's coarse ROM, Zen 3).
    Does nothing where this process already holds a compiled loop. Arguments as for march.
    """
    from hbm.ti import kernel

    if kernel.run_steps.signatures:
        return
    nb = system.n_boundary
    rec = Recording(start=1, stride=1, n_samples=1, dofs=np.arange(3 * nb), force_nodes=np.arange(nb),
                    section_stride=1, extreme_stride=1)
    zero = np.zeros(system.n_dof)
    Marcher(system, casing, mu, omega, zero, zero, dt, 1, rec, exponential).advance(1)


#: Largest casing profile tabulated (entries: steps of a casing period x nodes), 32 MB. The
#: sweep's at dt = 1e-7 s has 2 pi / (n_l Omega dt) x 9 entries: 0.71 million at 400 rad/s.
PROFILE_MAX_ENTRIES = 1 << 22


def casing_profile(casing: CasingOptions, theta: np.ndarray, omega: float, dt: float) -> np.ndarray:
    """d_j(tau) over one casing period, (P, n_b), m, when that period is P whole steps of dt
    (the sweep's steps are chosen so), else (0, n_b): the kernel then evaluates the casing law
    at every step.

    Row k holds hbm.contact.casing.casing_distance at tau = Omega k dt, the law's one source,
    for the nodes at angles theta ((n_b,), rad, signed by the sense of rotation). The kernel
    reads row m mod P at step m: at large tau its own floor rounds the lobe coordinate to
    1e-16 of tau (1e-13 rad after 200 revolutions); the table's, from tau < 2 pi / n_l, to 1e-16
    of that, so the two differ at round-off only.
    """
    theta = np.asarray(theta, dtype=float)
    if omega * dt <= 0.0:  # a casing at rest: no period
        return np.zeros((0, len(theta)))
    period = 2.0 * np.pi / (casing.n_lobes * omega * dt)
    n = int(round(period)) if np.isfinite(period) else 0
    # whole to round-off (the sweep's P is within a few ulp of n): a period whole to a
    # relative eps only shifts the table's phase by eps P steps every casing period, 0.03
    # steps after 200 revolutions at 400 rad/s for eps = 1e-9
    if n < 1 or abs(period - n) > 1e-14 * period or n * len(theta) > PROFILE_MAX_ENTRIES:
        return np.zeros((0, len(theta)))
    return np.ascontiguousarray(casing_distance(omega * (np.arange(n) * dt), theta, casing))


def _padded_columns(a: np.ndarray) -> np.ndarray:
    """a (n, n_b) padded with zero columns to 12 when n_b <= 12 (the kernel's fast path)."""
    from hbm.ti.kernel import FAST_NODES

    n, nb = a.shape
    if nb > FAST_NODES:
        return np.ascontiguousarray(a)
    out = np.zeros((n, FAST_NODES))
    out[:, :nb] = a
    return out

