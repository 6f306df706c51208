"""Options of the isola search (scene section [isolas])."""
from __future__ import annotations

import math
from dataclasses import dataclass

from hbm.options import check_flag, check_option


@dataclass(frozen=True)
class IsolaOptions:
    """The isola search (hbm.isolas.search) on the HBM residual.

    n_modes: modal seeds use the first n_modes modes Phi_j of the ROM (K, M), eq. (31).
      Default 4: the paper's isolas respond on 1B, 2B, 1T and the 4th mode.
    harmonics: the harmonics k of the seeds x0(t) = A Phi_j cos(k Omega t), multiples of
      Omega whatever the basis (in the basis of Omega / nu, harmonic k nu; those with k nu <=
      N_h are used). Default 1..10: the paper's engine orders (its isola 1 carries k = 4 and
      10).
    amplitudes: the dimensionless amplitudes A. A is the largest radial tip displacement
      of the seed divided by the tip radius (the mean radius of the contact nodes): Phi_j is
      scaled to a unit largest radial displacement over the contact nodes, then by A rho_tip.
      Default a log grid over [1e-3, 1e-2] (three points): on rotor 67 (rho_tip = 0.241 m)
      that is 0.24 to 2.4 mm, the LE amplitudes seen along the primary NFRC (0.3 to 2.4 mm,
      Fig. 6), which is how the paper chose its range.
    primary_amplitudes: the amplitudes A of a second family of modal seeds, eq. (31)'s shapes
      added to each of the primary NFRC's solutions at the grid speed (one per crossing of its
      curve with that speed): x0 = x_primary + A rho_tip Phi_j cos(k Omega t). The primary of
      rotor 67 holds only the casing's even harmonics; an odd harmonic added to it breaks that
      symmetry and leads to branches born from the primary or close to it (the narrow isolas
      near k Omega = omega_j), which eq. (31)'s seeds from rest reach only by chance: on the
      default scene they found none of the eight speeds' solutions these seeds reached (at
      400, 560, 680, 960 and 1160-1280 rad/s), each of those speeds from A = 1e-3, while
      A = 1e-2 added none. Default (1e-3,); () leaves the family out.
    n_omega: points of the seeds' Omega grid (evenly spaced over the range). Default 41 (the
      paper's 40 rad/s spacing over [400, 2000]).
    omega_min, omega_max: range of the seeds and of the branches' continuation, rad/s;
      None: the [hbm] range.
    tolerance: a converged solution (u, Omega) lies on a known branch when its distance to
      the branch's polyline in the continuation's scaled variables (u, the scaled unknowns
      alpha x~ ~ 1 per clearance; Omega / 100 rad/s) is below this, or when Newton at that
      Omega from the polyline's nearest point lands within tolerance / 100 of it. Default
      1e-2: 1 % of the casing clearance (4 um) in the tip displacement at the same Omega.
    max_points: most points of each half branch (each direction from a seed). Default 600:
      the halves of a closed loop share it (the longest seen on rotor 67, the coarse DLFT
      682-853 rad/s period-doubled loop, has 547 points in all, ~280 a half), so 600 leaves
      room for a finer step; an open branch that winds on (RL's coarse 486-1190 rad/s one)
      stops here in each half, at twice this in all.
    crawl_points: a half branch ends after this many successive points at a step below 4
      ds_min (status "crawled at the step floor"): such stretches cost a correction per
      ~1e-5 of arc length. Default 30.
    newton_iterations: Newton iterations allowed per seed (with backtracking): most seeds
      fail or converge fast; a cap keeps the failing ones cheap. Default 12.
    model_seed_iterations: Newton iterations allowed, without the stall rule, for a seed
      that is a solution of a model (the sweep's orbits; for RL, DLFT's solutions): it lies
      next to an HBM solution wherever the basis holds its orbit, but the contact law's
      kinks can keep Newton's residual from falling tenfold in three iterations. On the
      default rotor 67 scene the rule gave up on such seeds at ||R|| = 1e-3 (RL, 1110
      rad/s, basis Omega / 2); without it they converged in 8 to 47 iterations. Default 60.
    rl_branch_seeds: RL's seeds from each branch of DLFT's search (hbm.isolas.harmonic.rl_seeds):
      this many of its converged points, evenly spaced along it, besides DLFT's distinct seed
      solutions. A seed solution gives RL one speed of the branch, where RL's Newton may fail
      or RL's branch may not reach; on the default rotor 67 scene RL's patient Newton from
      every few points of DLFT's branches found RL's counterparts of DLFT's 400-429 and
      955-971 rad/s branches at most of them (6 of 9 and 8 of 13 points), both missed from
      the seed solutions. Default 8: with it the stage found three more RL branches on each
      of the default and coarse scenes, for 72 seeds and 17 s and 82 s more of RL's wall
      time (Zen 3 host); 0: none.
    harmonic_checks: points of each branch solved again with twice the harmonics (and AFT
      samples), in the middle of its longest stretch of monotone Omega
      (hbm.isolas.harmonic.harmonic_checks): a branch none of whose points has a solution with
      2 N_h next to it (within 25 %) is marked "not converged", one that holds at some
      "partly converged". The search keeps such branches (what is a truncation artefact at
      N_h is a matter of N_h); the file and Fig. 8 say which they are. A branch of 32 points
      or more is described in two halves on two processes, each checked at this many points.
      On the default rotor 67 scene (N_h = 40) none of the six points checked on RL's
      960-965 rad/s isola holds at N_h = 80, and time integration leaves its points; a check
      costs 0.1 to 1.9 s in the basis of Omega, 1 to 8 s in that of Omega / 2 (Zen 3 host).
      Default 3; 0: none.
    ti_seeds: also seed from every periodic time-integration point (ti.h5) whose orbit the
      HBM basis holds: omega = n_l Omega and omega = Omega, and with [hbm] subharmonic = 2
      omega = Omega / 2 as well (hbm.isolas.harmonic.ti_seeds).
    ti_period_doubled: with ti_seeds, also a second search in the basis of twice the
      period (Omega / (2 nu), 2 N_h harmonics), seeded only from the sweep's orbits of that
      period (omega = Omega / 2 for nu = 1), with every branch found so far known: the
      period-doubled branches time integration lands on. Its branches are written with the
      treatment's others (attribute subharmonic = 2 nu).
    workers: processes for the seeds' Newton corrections; None: every core this process
      may use (os.sched_getaffinity). Under mpirun the ranks share the seeds instead.
    """

    n_modes: int = 4
    harmonics: tuple[int, ...] = (1, 2, 3, 4, 5, 6, 7, 8, 9, 10)
    amplitudes: tuple[float, ...] = (1e-3, 3.1622776601683794e-3, 1e-2)
    primary_amplitudes: tuple[float, ...] = (1e-3,)
    n_omega: int = 41
    omega_min: float | None = None
    omega_max: float | None = None
    tolerance: float = 1e-2
    max_points: int = 600
    crawl_points: int = 30
    newton_iterations: int = 12
    model_seed_iterations: int = 60
    rl_branch_seeds: int = 8
    harmonic_checks: int = 3
    ti_seeds: bool = True
    ti_period_doubled: bool = True
    workers: int | None = None

    def __post_init__(self):
        check_option("n_modes", self.n_modes, 0, integer=True)
        if any(isinstance(k, bool) or not (math.isfinite(k) and int(k) == k >= 1) for k in self.harmonics):
            raise ValueError(f"harmonics must be integers >= 1, got {list(self.harmonics)}")
        for name in ("amplitudes", "primary_amplitudes"):
            values = getattr(self, name)
            if any(isinstance(a, bool) or not (a > 0 and math.isfinite(a)) for a in values):
                raise ValueError(f"{name} must be > 0, got {list(values)}")
        for name in ("harmonics", "amplitudes", "primary_amplitudes"):  # a repeated value seeds the same solutions twice
            values = list(getattr(self, name))
            twice = sorted({v for v in values if values.count(v) > 1})
            if twice:
                raise ValueError(f"{name} lists {', '.join(f'{v:g}' for v in twice)} more than once: {values}")
        check_option("n_omega", self.n_omega, 1, integer=True)
        lo, hi = self.omega_min, self.omega_max
        for k, v in (("omega_min", lo), ("omega_max", hi)):
            if v is not None:
                check_option(k, v, 0, low_open=True, unit="rad/s")
        if (lo is not None and lo <= 0) or (hi is not None and hi <= 0) or (lo is not None and hi is not None
                                                                            and not lo < hi):
            raise ValueError(f"need 0 < omega_min < omega_max, got {lo}, {hi}")
        check_option("tolerance", self.tolerance, 0, low_open=True)
        check_option("max_points", self.max_points, 2, integer=True)
        check_option("crawl_points", self.crawl_points, 1, integer=True)
        check_option("newton_iterations", self.newton_iterations, 1, integer=True)
        check_option("model_seed_iterations", self.model_seed_iterations, 1, integer=True)
        check_option("rl_branch_seeds", self.rl_branch_seeds, 0, integer=True)
        check_option("harmonic_checks", self.harmonic_checks, 0, integer=True)
        check_flag("ti_seeds", self.ti_seeds)
        check_flag("ti_period_doubled", self.ti_period_doubled)
        if self.workers is not None:
            check_option("workers", self.workers, 1, integer=True, note="or unset")

    def omega_range(self, hbm) -> tuple[float, float]:
        """(omega_min, omega_max), rad/s: these options' range, the [hbm] one where unset."""
        return (self.omega_min if self.omega_min is not None else hbm.omega_min,
                self.omega_max if self.omega_max is not None else hbm.omega_max)
