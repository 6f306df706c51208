"""Time integration started on a harmonic-balance orbit and compared with HBM orbits (section
3.3 of the reference paper, Figs. 9 and 10).

The ROM is marched n_periods periods T = 2 pi nu / Omega of the orbit (nu: the HBM basis'
subharmonic) with exact (Lagrange multiplier) contact, from the orbit's state at the instant
where it is farthest from the casing: started inside a contact phase, the first step of
the Lagrange-multiplier scheme would remove the HBM orbit's small penetration (DLFT's Gibbs
ripple, RL's penalty) in one step, an impulse of penetration / dt that throws the blade off
any orbit. The casing angle is shifted accordingly (theta_j + s Omega t0): the same problem
started at t0.
Two things are measured:

- whether time integration stays on the orbit: the distance to the orbit period by period
  (`deviation`), the growth of that distance over the march, and the period-to-period
  change over the last period (`drift`); a check of the orbit's stability verdict. When it
  leaves, where it goes: a node pressed on the casing over the whole last tenth of the
  march is told apart (`outcome` "permanent contact"): with friction above the
  contact set's friction-lock limit (rom.friction_lock) that is the lock, which a rubbing
  orbit's stability says nothing about; so is a march that settles on a state repeating
  every p > 1 periods (`repeat`): another orbit (a period-p orbit), whatever its distance;
- how the last period compares with each HBM orbit given (the orbit marched from, and the
  other contact treatment's orbit at the same Omega): radial displacement at the LE and TE
  sample by sample, and normal contact force. Forces are not compared sample by sample: the
  multiplier method delivers impacts as one-step impulses that no N_h-harmonic signal can
  follow, so the time-integration force is first projected on the HBM's own N_h harmonics
  (the Fourier coefficients of the force over the period, impulses included) and that
  truncated signal is compared with the HBM force (DLFT or regularised penalty). The HBM
  force is the one of its equilibrium: with RL that is the penalty force's harmonics
  filtered by the residual's Lanczos sigma, not the raw penalty force.

Every signal lives on one grid of n_time phases tau_i = 2 pi i / n_time of the basis
(tau = Omega t / nu, t = 0 the HBM orbit's time origin).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from hbm.contact.casing import casing_distance
from hbm.harmonic.fourier import FourierBasis
from hbm.options import CasingOptions
from hbm.ti.march import ModalSystem, Recording, march, rom_modal_system
from hbm.ti.sweep import steps_per_revolution

#: TI stays on an orbit when its distance to it over the last tenth of the periods is at most
#: GROWTH_TOL times that over the first BASELINE_PERIODS periods and at most DEVIATION_TOL of
#: the orbit's amplitude. Time integration starts on the HBM orbit, which is not its own
#: (DLFT's Gibbs ripple at the impacts, RL's penalty, the truncation: 10-30 % of the
#: amplitude, max norm, on the rotor 67 ROM at N_h = 40); that distance is reached within the
#: first period, and a stable orbit keeps it (the last 10 periods at 0.7-1.1 times the first
#: three, 0.11-0.22 of the amplitude, measured at 1960-2000 rad/s), whereas an unstable one
#: is left within a few periods (100 times the amplitude): 1.5 and 0.6 separate both
#: (tests/hbm/test_stability_rotor67.py). The baseline is the first three periods and not
#: the first tenth of the march: an unstable orbit next to a stable one (the other sheet
#: near a fold) is left within ten periods for a state that stays near it, and a baseline
#: that includes the departure calls that staying (on the default rotor 67 scene's DLFT
#: isola, 0.04 of the amplitude in the first period, 0.62 by the tenth, 0.58 at the end).
GROWTH_TOL = 1.5
DEVIATION_TOL = 0.6
BASELINE_PERIODS = 3
#: Newton from a march's last period (reached_orbit) finds the orbit itself (1e-13 to 5e-7 of
#: its norm away, measured on rotor 67) or another solution (20 % or more away, but 0.32 %
#: from a point of the unstable branch of a subcritical period doubling of the default scene's
#: DLFT NFRC, 0.3 rad/s from the doubling: the stable primary orbit, the distance being the
#: branch's odd-harmonic content): a solution farther than this from the orbit is another one
LANDING_TOL = 1e-3
#: A march that stays has settled when its last period repeats the one before to this fraction
#: of the amplitude (drift). On rotor 67 settled marches end at 0 to 0.02; one near an orbit
#: whose largest |mu| is 0.999 ends at 0.25 after 100 periods and settles after ~1500 (the
#: verdict says "unsettled" rather than calling such a march the orbit's confirmation).
SETTLED_DRIFT = 0.05
#: Lags (in periods) at which the last tenth of a march is tested for repeating (`repeat`): a
#: march from the coarse rotor 67 ROM's RL primary orbit (1459.5 rad/s, |mu| = 0.989) settles
#: within 100 periods on a state of period 2 T, up to 0.51 of the amplitude from the orbit, which
#: the drift over one period (0.36) alone would call "stays, unsettled".
MAX_REPEAT = 4
#: distances below this fraction of the amplitude count as on the orbit in the growth ratio
#: (an exact orbit's march: round-off, ~1e-12, whose ratio from period to period means nothing)
DEVIATION_FLOOR = 1e-3


@dataclass(frozen=True)
class ReachedOrbit:
    """Where a march went, in the HBM's unknowns: the harmonics of its last period against
    the orbit it started from, and the HBM solution Newton finds from them.

    distance: ||u_TI - u|| / ||u|| (u_TI: every retained dof's last period on the N_h
    harmonics, scaled as the residual's unknowns), -. converged: whether Newton at the same
    Omega from u_TI converged. solution_distance: ||u_N - u|| / ||u|| for that solution u_N
    (nan when it did not converge), -: about 0 when the march's periodic state belongs to the
    orbit, far from 0 when time integration went to another solution.
    period_ratio, orbit_period_ratio: g of that solution and of the orbit (their harmonics
    are multiples of g of the basis', their minimal period T / g; T the basis period,
    2 pi nu / Omega; hbm.stability.hill.harmonic_period), -: a march from a period-doubled
    orbit that settles next to the orbit of period 2 pi / Omega it was born from lands on a
    solution with twice the orbit's ratio. period_ratio is 0 when Newton did not converge
    (both 0 in files of earlier versions).
    """

    distance: float = field(metadata={"unit": "1"})
    converged: bool = field(metadata={"unit": "1"})
    solution_distance: float = field(metadata={"unit": "1"})
    period_ratio: int = field(default=0, metadata={"unit": "1"})
    orbit_period_ratio: int = field(default=0, metadata={"unit": "1"})

    def solution_percent(self) -> str:
        """solution_distance in per cent, e.g. "23 %", with two significant digits under 10 %:
        a solution just past LANDING_TOL (0.1 %) is not "0 %" from the orbit."""
        p = 100.0 * self.solution_distance
        return f"{p:.0f} %" if not p < 10.0 else f"{p:.2g} %"

    def period_words(self, subharmonic: int) -> str:
        """The words that name a landing on another minimal period than the orbit's, e.g.
        ", whose period is 1 revolution where the orbit's is 2 revolutions" (nu = subharmonic:
        the basis period is nu revolutions); "" when they are the same or either is unknown."""
        g, g0 = self.period_ratio, self.orbit_period_ratio
        if g <= 0 or g0 <= 0 or g == g0:
            return ""

        def revolutions(ratio: int) -> str:
            r = subharmonic / ratio
            return f"{r:.3g} revolution{'' if r == 1 else 's'}"

        return f", whose period is {revolutions(g)} where the orbit's is {revolutions(g0)}"


@dataclass(frozen=True)
class OrbitValidation:
    """Time integration marched from an HBM orbit, over the validation grid.

    omega: rotation speed Omega, rad/s. subharmonic: nu, the orbit's period is 2 pi nu /
    Omega. n_periods: periods marched. dt: time step, s. t0: start instant within the
    period, s. nodes: contact nodes of the three columns (LE, the second boundary node, TE),
    (3,). tau: grid phases 2 pi i / n_time, (n_time,), rad (t = tau nu / Omega).
    distance: casing distance d_j at those phases, (n_time, 3), m (contact when r_j = d_j).
    displacement: TI radial displacement over the last period, (n_time, 3), m.
    force: TI normal force over the last period projected on the orbit's N_h harmonics,
    (n_time, 3), N. force_peak: largest unprojected TI force over the last period, (3,), N: the
    peak of the multipliers averaged over each recording interval T / n_time (the force
    samples are such block means), not of the single steps' multipliers, so it grows with
    n_time towards the impulses' one-step peaks.
    deviation: (n_periods, 2), max over each period of |r_TI - r_HBM| at the LE and TE
    relative to the HBM orbit's half peak-to-peak radial displacement there, -.
    drift: max over the last period of |r(t) - r(t - T)| relative to the same amplitude, (2,), -.
    repeat: the smallest p <= MAX_REPEAT such that over the last tenth of the periods (at least
    p + 1 of them) |r(t) - r(t - p T)| <= SETTLED_DRIFT times the amplitude at the LE and TE,
    p > 1 only when that window is not a transient decaying towards a T-periodic state
    (repeat_period); 0 when there is none (not settled, or a longer period). p > 1: the march
    left the orbit for a state of period p T, which is not the orbit's (stays is then False).
    growth: deviation over the last tenth of the periods over that of the first
    BASELINE_PERIODS periods (fewer when a tenth is fewer), both raised to DEVIATION_FLOOR (max
    over LE and TE), -. stays: growth <= GROWTH_TOL and that last deviation (last_deviation)
    <= DEVIATION_TOL.
    max_penetration: largest r_j - d_j after the contact correction, m.
    contact_fraction: share of the time steps of the last tenth of the periods in which each
    boundary node (LE to TE) carries a normal force (lam > 0), (n_b,), -: counted step by step
    (March.force_steps), not from the force samples, whose block means are > 0 as soon as one
    step of their block is in contact. 1 for a node in contact at every step.
    outcome: "stays" (= stays), "permanent contact" (left the orbit, and a node never lets go
    of the casing over the last tenth of the periods, contact_fraction 1: the friction lock
    when mu >= the ROM's mu_set), "another solution" (within the distance bounds, but the HBM
    solution through the last period is another one: see reached) or "leaves" (anything else).
    last_harmonics: every dof's harmonics over the last period, in the orbit's basis and time
    origin, (2 N_h + 1, n), m, eq. (5) order; empty unless asked for (record_all).
    reached: where the march went in the HBM's unknowns (reached_orbit), None unless asked.
    active_set_failures: steps whose contact solve hit its iteration cap and kept a clipped
    iterate (March.active_set_failures): their contact forces are approximate, and the verdict
    says so. explicit_direction_steps: contact steps whose friction direction did not settle
    and took the prediction's (March.explicit_direction_steps); the verdict says so too.
    """

    omega: float = field(metadata={"unit": "rad/s"})
    subharmonic: int = field(metadata={"unit": "1"})
    n_periods: int = field(metadata={"unit": "1"})
    dt: float = field(metadata={"unit": "s"})
    t0: float = field(metadata={"unit": "s"})
    nodes: np.ndarray = field(metadata={"unit": "1"})
    tau: np.ndarray = field(metadata={"unit": "rad"})
    distance: np.ndarray = field(metadata={"unit": "m"})
    displacement: np.ndarray = field(metadata={"unit": "m"})
    force: np.ndarray = field(metadata={"unit": "N"})
    force_peak: np.ndarray = field(metadata={"unit": "N"})
    deviation: np.ndarray = field(metadata={"unit": "1"})
    drift: np.ndarray = field(metadata={"unit": "1"})
    growth: float = field(metadata={"unit": "1"})
    stays: bool = field(metadata={"unit": "1"})
    max_penetration: float = field(metadata={"unit": "m"})
    contact_fraction: np.ndarray = field(default_factory=lambda: np.zeros(0), metadata={"unit": "1"})
    outcome: str = ""
    repeat: int = field(default=0, metadata={"unit": "1"})
    last_harmonics: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)), metadata={"unit": "m"})
    reached: ReachedOrbit | None = None
    active_set_failures: int = field(default=0, metadata={"unit": "1"})
    explicit_direction_steps: int = field(default=0, metadata={"unit": "1"})

    @property
    def locked_nodes(self) -> np.ndarray:
        """Boundary nodes (LE = 0) in contact over the whole last tenth of the march, (k,)."""
        return np.flatnonzero(np.asarray(self.contact_fraction) >= 1.0)

    @property
    def last_deviation(self) -> float:
        """The deviation over the last tenth of the periods that `stays` is judged on (max over
        those periods, LE and TE), -."""
        return float(np.asarray(self.deviation)[-last_tenth(self.n_periods):].max())

    @property
    def settled(self) -> bool:
        """Whether the last period repeats the one before within SETTLED_DRIFT (LE and TE)."""
        return bool(np.max(self.drift) <= SETTLED_DRIFT)

    def verdict(self) -> str:
        """The outcome in words (_verdict), followed by the counts of steps whose contact solve
        hit its iteration cap or whose friction direction did not settle, when there are any:
        numerical failures, not dynamical ones."""
        text = self._verdict()
        if self.active_set_failures > 0:
            text += f" (the contact solve hit its iteration cap at {self.active_set_failures} steps)"
        if self.explicit_direction_steps > 0:
            text += (f" (the friction's direction did not settle at {self.explicit_direction_steps} steps,"
                     " which took the prediction's)")
        return text

    def _verdict(self) -> str:
        """In words: "stays", "stays, unsettled (drift 0.36)" when the last period does not
        repeat the one before (SETTLED_DRIFT), "leaves for an orbit of period 2 T" (repeat),
        "leaves", "leaves for permanent contact (TE)" naming the locked nodes (LE, TE, or
        "node j" counted from the LE at 0), or "leaves: the march went to NaN or inf from
        period k" (a numerical failure, not a dynamical verdict)."""
        bad = ~np.isfinite(np.asarray(self.deviation, float)).all(axis=-1)
        if bad.any():
            return f"leaves: the march went to NaN or inf from period {int(np.argmax(bad)) + 1}"
        if self.stays:
            return "stays" if self.settled else f"stays, unsettled (drift {np.max(self.drift):.2f})"
        if self.repeat > 1 and self.outcome != "permanent contact":
            return (f"leaves for an orbit of period {self.repeat} T (the last tenth repeats every {self.repeat} "
                    f"periods, not every one: drift {np.max(self.drift):.2f})")
        if self.outcome == "another solution" and self.reached is not None:
            return (f"leaves for another solution ({self.reached.solution_percent()} from the orbit"
                    f"{self.reached.period_words(self.subharmonic)}, by Newton from the last period)")
        if self.outcome != "permanent contact":
            return "leaves"
        nb = len(self.contact_fraction)
        names = ["LE" if j == 0 else "TE" if j == nb - 1 else f"node {j}" for j in self.locked_nodes]
        return f"leaves for permanent contact ({', '.join(names)})"


@dataclass(frozen=True)
class OrbitComparison:
    """One HBM orbit against the time integration's last period, on the validation grid.

    source: where the orbit comes from, in words. converged: whether it is a solution (when
    not, the signals are nan and source says why). displacement: HBM radial displacement,
    (n_time, 3), m. force: HBM normal force, (n_time, 3), N (columns as OrbitValidation): the
    force of the HBM equilibrium, i.e. sigma_k F_k(lam) with the residual's filter sigma on
    the force harmonics (RL with Lanczos: the sigma-filtered penalty force; force_filter says
    which). force_filter: "none" or "sigma" (the residual's sigma applied).
    displacement_error: max_t |r_TI - r_HBM| over the HBM orbit's half peak-to-peak radial
    displacement, at the LE and TE, (2,), - (the scale of OrbitValidation.deviation: the
    static offset of r does not enter).
    force_error: max_t |lam_TI,Nh - lam_HBM| / max_t max(|lam_HBM|, |lam_TI,Nh|) at the LE and
    TE, (2,), - (0 where neither is ever in contact, nan where a force is nan); the normal
    force is one-sided (>= 0, 0 off contact), so its maximum is its peak-to-peak and the scale
    holds no offset.
    multiplier: largest |mu| of this orbit by Hill's method with its own treatment's Jacobian,
    over its minimal period, -; n_unstable: its multipliers outside the unit circle. Both treatments
    are analysed at every point, so a stability verdict of each stands beside time integration's
    (nan and -1 when the orbit was not analysed).
    """

    source: str
    converged: bool = field(metadata={"unit": "1"})
    displacement: np.ndarray = field(metadata={"unit": "m"})
    force: np.ndarray = field(metadata={"unit": "N"})
    displacement_error: np.ndarray = field(metadata={"unit": "1"})
    force_error: np.ndarray = field(metadata={"unit": "1"})
    force_filter: str = "none"
    multiplier: float = field(default=float("nan"), metadata={"unit": "1"})
    n_unstable: int = field(default=-1, metadata={"unit": "1"})


def validation_nodes(n_boundary: int) -> np.ndarray:
    """The three compared contact nodes: LE (0), the second boundary node, TE (n_b - 1)."""
    return np.array([0, min(1, n_boundary - 1), n_boundary - 1])


def last_tenth(n_periods: int) -> int:
    """Periods in the last tenth of a march of n_periods (at least 1), on which it is judged."""
    return max(1, int(n_periods) // 10)


def half_ptp(r: np.ndarray) -> np.ndarray:
    """An orbit's amplitude: half the peak-to-peak of r, (n_time, k) -> (k,), r's unit (raised
    to 1e-300 to divide by)."""
    return np.maximum(0.5 * np.ptp(np.asarray(r, dtype=float), axis=0), 1e-300)


def departure(deviation: np.ndarray) -> tuple[float, bool]:
    """Whether a march stays on its orbit, from its distance to it period by period.

    deviation: (n_periods, k) distance to the orbit over each period, relative to the orbit's
    amplitude (k signals, e.g. LE and TE), -. Returns (growth, stays): growth is the largest
    over the k signals of the distance over the last tenth of the periods over that over the
    first BASELINE_PERIODS (at most a tenth), both raised to DEVIATION_FLOOR; stays is growth
    <= GROWTH_TOL and the last tenth's distance <= DEVIATION_TOL.
    """
    d = np.asarray(deviation, dtype=float)
    if d.ndim != 2 or len(d) < 1:
        raise ValueError(f"deviation must be (n_periods, k) with n_periods >= 1, got {d.shape}")
    n10 = last_tenth(len(d))
    first = d[:min(BASELINE_PERIODS, n10)].max(axis=0)
    last = d[-n10:].max(axis=0)
    growth = float(np.max(np.maximum(last, DEVIATION_FLOOR) / np.maximum(first, DEVIATION_FLOOR)))
    return growth, bool(growth <= GROWTH_TOL and last.max() <= DEVIATION_TOL)


def repeat_period(x: np.ndarray, amplitude: np.ndarray, n_last: int, max_repeat: int = MAX_REPEAT,
                  tol: float = SETTLED_DRIFT) -> int:
    """The smallest lag p <= max_repeat (in periods) at which the last max(n_last, p + 1)
    periods of x repeat: max |x[k] - x[k - p]| <= tol amplitude for every signal; 0 if none.
    A lag p > 1 is not taken when those periods are a transient decaying towards a T-periodic
    state (_decays_to_period_one): along a multiplier near -1 such a transient alternates
    from period to period and repeats at lag 2 long before its lag-1 difference is within tol.

    x: (n_periods, n_time, k) signals period by period, m. amplitude: (k,) their scale, m.
    """
    x = np.asarray(x, dtype=float)
    scale = np.maximum(np.asarray(amplitude, dtype=float), 1e-300)
    for p in range(1, max_repeat + 1):
        n = max(n_last, p + 1)
        if n > len(x):
            break
        w = x[-n:]
        if (np.abs(w[p:] - w[:-p]).max(axis=(0, 1)) / scale <= tol).all():
            if p == 1 or not _decays_to_period_one(w, scale, tol):
                return p
    return 0


def _decays_to_period_one(w: np.ndarray, scale: np.ndarray, tol: float) -> bool:
    """Whether the periods w, (n, n_time, k), are a transient decaying towards a T-periodic state.

    Their lag-1 difference (max over the period relative to scale, (k,), worst signal), averaged
    over three equal runs of periods as a > b > c, is extrapolated by Aitken's delta-squared,
    exact for D + C q^k: limit D = c - (b - c) q / (1 - q), q = (b - c) / (a - b). A limit <= tol
    is a T-periodic state; above tol, a state of longer period that the march approaches. A
    difference that does not shrink, or not geometrically (q >= 1), extrapolates nothing: False,
    as with fewer than 4 periods.
    """
    d1 = (np.abs(np.diff(w, axis=0)).max(axis=1) / scale).max(axis=1)  # (n - 1,)
    m = len(d1) // 3
    if m < 1:
        return False
    a, b, c = d1[len(d1) - 3 * m:].reshape(3, m).mean(axis=1)
    if not a > b > c:
        return False
    q = (b - c) / (a - b)
    return bool(q < 1.0 and c - (b - c) * q / (1.0 - q) <= tol)


def grid_size(n_harmonics: int, minimum: int = 1024) -> int:
    """Samples per period of the validation grid: a power of 2, at least `minimum` and
    enough for n_harmonics. 1024 by default: the time integration's forces are block means
    over n_per / n_time steps, which attenuate harmonic k by sin(x) / x, x = pi k / n_time:
    0.25 % at k = 40."""
    n = int(minimum)
    while n < 2 * n_harmonics + 2:
        n *= 2
    return n


def march_from_hbm(rom, casing: CasingOptions, mu: float, coeffs: np.ndarray, omega: float, *,
                   subharmonic: int = 1, n_periods: int = 100, dt: float = 1e-7,
                   n_time: int | None = None, record_all: bool = False) -> OrbitValidation:
    """March n_periods from an HBM orbit and measure how far time integration stays from it.

    rom: RomModel (or a hbm.ti.march.ModalSystem). coeffs: the orbit's full-dof harmonics,
    (2 N_h + 1, n), m, eq. (5) order, in the basis of omega / subharmonic (omega = Omega,
    rad/s). dt: largest step, s (shrunk so that a period is a multiple of n_time steps).
    n_time: grid samples per period (default grid_size(N_h)). record_all: record every dof
    (n_periods n_time n doubles) to return the last period's harmonics (last_harmonics), e.g.
    to solve the HBM again from where time integration went.
    """
    system = rom if isinstance(rom, ModalSystem) else rom_modal_system(rom)
    c = np.asarray(coeffs, dtype=float)
    if c.ndim != 2 or c.shape[1] != system.n_dof or c.shape[0] % 2 != 1:
        raise ValueError(f"coeffs must be (2 N_h + 1, {system.n_dof}), got {c.shape}")
    if n_periods < 3:
        raise ValueError(f"need n_periods >= 3, got {n_periods}")
    nh = (c.shape[0] - 1) // 2
    nb = system.n_boundary
    nodes = validation_nodes(nb)
    cols = 3 * nodes
    grid = FourierBasis(nh, int(n_time or grid_size(nh)))
    n_s = grid.n_time
    w = omega / subharmonic  # the basis' fundamental, rad/s
    n_per = steps_per_revolution(w, dt, n_s)
    h = 2.0 * np.pi / (w * n_per)
    stride = n_per // n_s
    sense = system.rotation
    # start on a grid phase where the orbit is farthest from the casing
    r_all = grid.to_time(c[:, 0:3 * nb:3])  # (n_s, n_b)
    d_all = casing_distance(subharmonic * grid.tau, sense * system.theta, casing)
    i0 = int(np.argmax((d_all - r_all).min(axis=1)))
    t0 = grid.tau[i0] / w
    k = np.arange(1, nh + 1)[:, None]
    ph = k * grid.tau[i0]
    x0 = c[0] + (c[1::2] * np.cos(ph) + c[2::2] * np.sin(ph)).sum(axis=0)
    v0 = (k * w * (-c[1::2] * np.sin(ph) + c[2::2] * np.cos(ph))).sum(axis=0)
    shifted = replace(system, theta=system.theta + sense * omega * t0)  # the same problem started at t0
    # forces of every contact node: a node other than the three compared may be the one that locks
    dofs = np.arange(system.n_dof) if record_all else cols
    rec = Recording(start=stride, stride=stride, n_samples=n_periods * n_s, dofs=dofs, force_nodes=np.arange(nb))
    # one stride more than the recorded span: the last force sample is a block mean reaching
    # half a stride past it (multipliers of steps never marched read 0)
    m = march(shifted, casing, mu, omega, x0, v0, h, n_periods * n_per + stride, rec)
    x = m.displacement[:, cols] if record_all else m.displacement
    x = x.reshape(n_periods, n_s, 3)
    f_all = m.normal_force.reshape(n_periods, n_s, nb)
    f = f_all[:, :, nodes]
    at = (i0 + 1 + np.arange(n_s)) % n_s  # grid index of each sample of a period
    ref = grid.to_time(c[:, cols])  # (n_s, 3)
    amp = half_ptp(ref)
    dev = (np.abs(x - ref[at]).max(axis=1) / amp)[:, [0, 2]]
    drift = (np.abs(x[-1] - x[-2]).max(axis=0) / amp)[[0, 2]]
    n10 = last_tenth(n_periods)
    growth, stays = departure(dev)
    repeat = repeat_period(x[:, :, [0, 2]], amp[[0, 2]], n10)
    stays = stays and repeat <= 1
    # Permanent contact does not ask the march to have settled: past the friction-lock limit
    # the contact response is not unique, and a locked node's force may wander from period
    # to period (by 1-2 % on the two-node toy of tests/hbm/test_friction_lock_ti.py).
    # share of the steps of the last tenth with a force (the force blocks tile those steps)
    steps = m.force_steps.reshape(n_periods, n_s, nb)
    in_contact = steps[-n10:].sum(axis=(0, 1)) / (n10 * n_s * stride)
    outcome = "stays" if stays else ("permanent contact" if (in_contact >= 1.0).any() else "leaves")
    disp = np.empty((n_s, 3))
    disp[at] = x[-1]
    force = np.empty((n_s, 3))
    force[at] = f[-1]
    last = np.zeros((0, 0))
    if record_all:
        full = np.empty((n_s, system.n_dof))
        full[at] = m.displacement[-n_s:]
        last = grid.to_freq(full)
    return OrbitValidation(omega=float(omega), subharmonic=int(subharmonic), n_periods=int(n_periods), dt=float(h),
                           t0=float(t0), nodes=nodes, tau=grid.tau, distance=d_all[:, nodes], displacement=disp,
                           force=grid.to_time(grid.to_freq(force)), force_peak=f[-1].max(axis=0), deviation=dev,
                           drift=drift, growth=growth, stays=stays, max_penetration=float(m.max_penetration),
                           contact_fraction=in_contact, outcome=outcome, repeat=repeat, last_harmonics=last,
                           active_set_failures=int(m.active_set_failures),
                           explicit_direction_steps=int(m.explicit_direction_steps))


def reached_orbit(res, ti: OrbitValidation, u: np.ndarray, omega: float) -> ReachedOrbit:
    """Compare a march recorded with record_all=True (ti) with the orbit u it started from.

    res: the orbit's HarmonicBalanceResidual (its basis is ti's). u: the orbit's unknowns,
    ((2 N_h + 1) n_r,), -. omega: Omega, rad/s. Newton is damped (hbm.harmonic.start), as the
    validation stage solves the other treatment's orbit.
    """
    from hbm.continuation.newton import NewtonOptions
    from hbm.harmonic.solver import HbmSolver
    from hbm.harmonic.start import damped_newton
    from hbm.stability.hill import harmonic_period

    if ti.last_harmonics.size == 0:
        raise ValueError("the march kept no last period: march_from_hbm(..., record_all=True)")
    u = np.asarray(u, dtype=float)
    norm = max(float(np.linalg.norm(u)), 1e-300)
    u_ti = res.to_unknowns(ti.last_harmonics[:, : res.n_r])
    # damped_newton's own cap (40 iterations) applies: an options' max_iter is replaced by it
    sol = damped_newton(res, u_ti, omega, NewtonOptions(tol_residual=1e-8), HbmSolver(atol=1e-9))
    back = float(np.linalg.norm(sol.x - u)) / norm if sol.converged else float("nan")
    g = harmonic_period(res.to_coefficients(sol.x)) if sol.converged else 0
    return ReachedOrbit(float(np.linalg.norm(u_ti - u)) / norm, bool(sol.converged), back, g,
                        harmonic_period(res.to_coefficients(u)))


def confirm_orbit(res, ti: OrbitValidation, u: np.ndarray, omega: float) -> OrbitValidation:
    """ti with `reached` filled in, and a march the distance rule keeps turned into "another
    solution" when Newton from its last period converges to a solution more than
    LANDING_TOL from the orbit (ti recorded with record_all=True; arguments as reached_orbit).
    A Newton that does not converge leaves the verdict as it is: it says nothing of where
    the march went."""
    went = reached_orbit(res, ti, u, omega)
    if ti.stays and went.converged and went.solution_distance > LANDING_TOL:
        return replace(ti, stays=False, outcome="another solution", reached=went)
    return replace(ti, reached=went)


def compare_with_hbm(ti: OrbitValidation, coeffs: np.ndarray | None, forces: np.ndarray | None,
                     source: str, sigma: np.ndarray | None = None) -> OrbitComparison:
    """An HBM orbit against the time integration `ti` (same Omega and subharmonic).

    coeffs: the orbit's full-dof harmonics (2 N_h + 1, n), m, in ti's basis; None when there
    is no orbit (source then says why). forces: its normal forces lam on its own AFT grid
    (N_t, n_b), N (e.g. HarmonicBalanceResidual.signals(...)["lam"]). sigma: the residual's
    filter on the force harmonics (HarmonicBalanceResidual.sigma), (2 N_h + 1,), -; the HBM
    force compared is sigma_k F_k(lam), the one in the HBM equilibrium (RL with Lanczos: the
    sigma-filtered penalty force, not lam); None: no filter (DLFT). Both treatments use the
    scene's N_h, so ti.force (projected on the marched orbit's N_h) is compared as it is.
    """
    n_s = len(ti.tau)
    nan = np.full((n_s, 3), np.nan)
    if coeffs is None:
        return OrbitComparison(source, False, nan, nan, np.full(2, np.nan), np.full(2, np.nan))
    c = np.asarray(coeffs, dtype=float)
    nh = (c.shape[0] - 1) // 2
    grid = FourierBasis(nh, n_s)
    disp = grid.to_time(c[:, 3 * ti.nodes])
    lam = np.asarray(forces, dtype=float)
    harmonics = FourierBasis(nh, lam.shape[0]).to_freq(lam[:, ti.nodes])
    filtered = sigma is not None and not np.all(np.asarray(sigma) == 1.0)
    if filtered:
        harmonics = np.asarray(sigma, dtype=float)[:, None] * harmonics
    return replace(_compared(ti, source, disp, grid.to_time(harmonics)), force_filter="sigma" if filtered else "none")


def compare_again(ti: OrbitValidation, previous: OrbitComparison) -> OrbitComparison:
    """The HBM orbit of `previous` (compared with another march from the same orbit, on the
    same grid) against the march `ti`: its signals and Hill verdict kept, the differences
    computed again."""
    if not previous.converged:
        return previous
    if previous.displacement.shape[0] != len(ti.tau):
        raise ValueError(f"the comparison holds {previous.displacement.shape[0]} phases, the march "
                         f"{len(ti.tau)}: not the same grid")
    fresh = _compared(ti, previous.source, previous.displacement, previous.force)
    return replace(previous, displacement_error=fresh.displacement_error, force_error=fresh.force_error)


def _compared(ti: OrbitValidation, source: str, disp: np.ndarray, hbm_f: np.ndarray) -> OrbitComparison:
    """OrbitComparison of the HBM displacement disp and force hbm_f, (n_time, 3) on ti's grid."""
    ti_f = ti.force
    cols = [0, 2]
    derr = np.abs(ti.displacement - disp).max(axis=0)[cols] / half_ptp(disp)[cols]
    scale = np.maximum(np.abs(hbm_f).max(axis=0), np.abs(ti_f).max(axis=0))[cols]
    diff = np.abs(ti_f - hbm_f).max(axis=0)[cols]
    # 0 only where neither force is ever in contact; a nan force (a march that blew up) stays nan
    ferr = np.where(scale == 0, 0.0, diff / np.where(scale == 0, 1.0, scale))
    return OrbitComparison(source, True, disp, hbm_f, derr, ferr)
