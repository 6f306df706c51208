"""Options of the nonlinear stages (scene sections [casing], [contact], [hbm], [ti])."""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass


def check_option(name: str, value, low=None, high=None, *, low_open: bool = False, high_open: bool = False,
                 integer: bool = False, unit: str = "", note: str = "") -> None:
    """Raise ValueError, naming the option, its value and the allowed range, unless `value` is a
    finite real number (an integer when `integer`; a bool is neither) within [low, high] (an
    end left open by low_open / high_open; None: unbounded there). unit and note (what the
    bound means) follow the range in the message.

    One check for every options dataclass of hbm: these are built from Python as well as from
    scenes, and a NaN, an infinity or a fractional count is otherwise refused far from its
    cause, or not at all (a NaN fails every comparison, so `if x < 0: raise` lets it through).
    """
    if low is not None and high is not None:
        allowed = f"in {'(' if low_open else '['}{low:g}, {high:g}{')' if high_open else ']'}"
    elif low is not None:
        allowed = f"{'>' if low_open else '>='} {low:g}"
    elif high is not None:
        allowed = f"{'<' if high_open else '<='} {high:g}"
    else:
        allowed = ""
    allowed = " ".join(part for part in (allowed, unit, f"({note})" if note else "") if part)
    got = value if isinstance(value, numbers.Number) else repr(value)
    if (isinstance(value, bool) or not isinstance(value, numbers.Integral if integer else numbers.Real)
            or not math.isfinite(value)):
        kind = "an integer" if integer else "a finite number"
        raise ValueError(f"{name} must be {kind}{' ' + allowed if allowed else ''}, got {got}")
    if not ((low is None or (value > low if low_open else value >= low))
            and (high is None or (value < high if high_open else value <= high))):
        raise ValueError(f"{name} must be {allowed}, got {got}")


def check_flag(name: str, value) -> None:
    """Raise ValueError unless `value` is true or false (a bool, numpy's included, or 0 / 1): a
    string such as "false" is truthy, and would switch the option on without a word."""
    if isinstance(value, str) or value not in (True, False):
        raise ValueError(f"{name} must be true or false, got {value!r}")


@dataclass(frozen=True)
class CasingOptions:
    """Rigid ovalised casing, eq. (28) of the reference paper.

    n_lobes: number of lobes n_l. width: angular width w_l of a lobe, rad.
    clearance: operating clearance c_j, m. penetration: lobe penetration p_j, m.
    """

    n_lobes: int = 2
    width: float = 0.15
    clearance: float = 4e-4
    penetration: float = 1.25e-4

    def __post_init__(self):
        check_option("n_lobes", self.n_lobes, 1, integer=True)
        if not 0 < self.width < 2 * math.pi:
            raise ValueError(f"width must be in (0, 2 pi) rad, got {self.width}")
        check_option("clearance", self.clearance, 0, unit="m")
        check_option("penetration", self.penetration, unit="m")  # <= 0 is valid (no contact), the scene warns


@dataclass(frozen=True)
class ContactOptions:
    """Contact and friction laws.

    epsilon: DLFT weighting factor, N/m. kappa: RL penalty stiffness, N/m.
    gamma: RL regularisation, N. lanczos: apply the Lanczos sigma filter (RL).
    mu: sliding Coulomb friction coefficient, -.
    """

    epsilon: float = 1e7
    kappa: float = 1e9
    gamma: float = 600.0
    lanczos: bool = True
    mu: float = 0.15

    def __post_init__(self):
        for k in ("epsilon", "kappa"):
            check_option(k, getattr(self, k), 0, low_open=True, unit="N/m")
        check_option("gamma", self.gamma, 0, unit="N")
        check_option("friction coefficient mu", self.mu, 0)
        check_flag("lanczos", self.lanczos)


@dataclass(frozen=True)
class HbmOptions:
    """Harmonic balance and its continuation (scene section [hbm]).

    methods: contact treatments to run, among "dlft", "rl".
    n_harmonics: N_h. n_time: N_t, samples per period in the AFT (>= 2 N_h + 2: for an even
      N_t every retained harmonic then lies below the Nyquist bin, which has no sine part; an
      odd N_t = 2 N_h + 1 would be exact for the AFT too, but the stability and content code
      is only exercised on even N_t, so the one bound stays). A scene also needs N_t to be a
      multiple of the casing's lobes times subharmonic (pipelines.scene): on another grid the
      AFT breaks the casing's symmetry and the primary branch's branch points become imperfect.
    omega_min, omega_max: rotation speed range Omega, rad/s (omega = Omega).
    start: where the branch starts, "omega_max" (the default: at 2000 rad/s the contact-free
      solution is a good start for both treatments on rotor 67, while at 400 rad/s RL's stiff
      law has no start within Newton's reach) or "omega_min"; it then runs to the other end.
    max_points: most points of one branch (the run stops with that status beyond it).
    ds_max: largest arc-length step, in the continuation's scaled units (u ~ 1, 100 rad/s):
      5 lets the step grow on the long flat stretches (with 0.5 the step sat at the cap on
      almost every point: 2911 points instead of 338 for RL at N_h = 10, same peaks).
    tolerance: Newton's test on the scaled residual ||R|| (R ~ H_r / (k_ref / alpha)).
    stability: Floquet stability of every point and the bifurcations of the branch
      (Hill's method, hbm.stability). Off by default: it adds 0.8-1.4 (RL) to 1.1-2.0 (DLFT)
      times the NFRC's own time on the coarse rotor 67 ROM (about 470 and 320 analyses of
      ~0.13 s CPU each, see hbm.stability.monitor).
    stability_max_gap: most points between two Floquet analyses (the monitor analyses
      sooner where multipliers approach the unit circle). 8 analyses about half the points
      of the coarse rotor 67 NFRCs; 1 analyses every point (1.9 times the analyses) and so
      also finds the short stretches of the other stability that lie inside one gap (a pair
      of crossings a few rad/s apart: 4 of 53 and 8 of 87 crossings are missed with 8 on the
      coarse DLFT and RL NFRCs).
    refine_bifurcations: with stability, points solved and analysed per bifurcation (not a
      fold) to locate it finer than the branch's points (Brent's method on the crossing
      multiplier, hbm.stability.refinement); 0 (the default) interpolates between the two
      points around it, whose spacing then bounds the error.
    subharmonic: nu, the HBM's fundamental is omega = Omega / nu (nu = 1: the casing's
      period; nu = 2 holds the period-doubled orbits). The continuation parameter stays
      Omega.
    """

    methods: tuple[str, ...] = ("dlft", "rl")
    n_harmonics: int = 40
    n_time: int = 1024
    omega_min: float = 400.0
    omega_max: float = 2000.0
    start: str = "omega_max"
    max_points: int = 4000
    ds_max: float = 5.0
    tolerance: float = 1e-8
    stability: bool = False
    stability_max_gap: int = 8
    refine_bifurcations: int = 0
    subharmonic: int = 1

    def __post_init__(self):
        for m in self.methods:
            if m not in ("dlft", "rl"):
                raise ValueError(f"unknown HBM method '{m}'; known: dlft, rl")
        if len(set(self.methods)) != len(self.methods):
            raise ValueError(f"methods {list(self.methods)} names a method twice")
        check_option("n_harmonics", self.n_harmonics, 1, integer=True)
        check_option("n_time", self.n_time, 4, integer=True)
        if self.n_time < 2 * self.n_harmonics + 2:
            raise ValueError(f"n_time = {self.n_time} cannot resolve {self.n_harmonics} harmonics "
                             f"(need n_time >= 2 n_harmonics + 2 = {2 * self.n_harmonics + 2})")
        for k in ("omega_min", "omega_max"):
            check_option(k, getattr(self, k), 0, low_open=True, unit="rad/s")
        if not 0 < self.omega_min < self.omega_max:
            raise ValueError(f"need 0 < omega_min < omega_max, got {self.omega_min}, {self.omega_max}")
        if self.start not in ("omega_min", "omega_max"):
            raise ValueError(f"start must be 'omega_min' or 'omega_max', got {self.start!r}")
        check_option("max_points", self.max_points, 2, integer=True)
        check_option("ds_max", self.ds_max, 0, low_open=True)
        check_option("tolerance", self.tolerance, 0, 1, low_open=True, high_open=True)
        check_flag("stability", self.stability)
        check_option("stability_max_gap", self.stability_max_gap, 1, integer=True, note="1: every point analysed")
        check_option("refine_bifurcations", self.refine_bifurcations, 0, integer=True, note="0: no refinement")
        check_option("subharmonic", self.subharmonic, 1, integer=True)


@dataclass(frozen=True)
class ValidationOptions:
    """The validation points (section 3.3 of the reference paper): time integration marched
    from a stable point near the primary resonance, from a point of an isola and from a point
    of the period-doubled branch, compared with both HBM treatments.

    n_periods: periods marched from each point (the paper's 100). n_candidates: Floquet
    analyses near a branch's peak to find a stable point (24: on the coarse rotor 67 ROM at
    N_h = 40 DLFT's first stable candidate is among the first 8, whereas RL's whole peak
    region is unstable and 16 candidates find no stable point; 24 find one at 60 % of the
    peak; ~0.7 s each; when none is stable, the NFRC's stability is computed along it).
    n_scan: points analysed along a branch whose file holds no stability, to find where it
    changes (24: the cost of about 2 % of an NFRC at N_h = 40; a stretch between two scanned
    points can hide two changes, and when the scan finds no period doubling whose branch
    switch converges the NFRC's stability is computed along it). pd_points: most
    points of the period-doubled branch each way from the switch. pd_tries: period doublings
    tried until time integration stays on the doubled branch's point: the NFRC's first, then
    (when the isola search stored stability) those that end a stable stretch of one of its
    branches, longest stretch first. Default 4: on the coarse rotor 67 ROM the points of the
    NFRCs' doubled branches, Hill-stable, fall into the friction lock under time
    integration, and so do those of two of DLFT's detached branch; the 820 rad/s one of that
    branch is kept. Each try costs a switch, 2 pd_points continuation points with stability
    and a march (~2-3 min there). primary_tries: primary points tried until time integration
    stays on one, each outside the stable stretches of those tried before, the retries with a
    verdict the march can check (pipelines.stages.validation.DECISIVE_DECAY). Default 3: on
    the coarse rotor 67 ROM with stored stability time integration leaves DLFT's largest
    stable amplitude (1335 rad/s) for the friction lock and keeps the retry (1647 rad/s); on
    the default scene it leaves DLFT's (1088 rad/s) and keeps the retry (1339 rad/s). A try
    costs one march (~1-2 min there). isola_tries: the same for the isola point, over the
    stable stretches of all the isola search's branches of kind isola, then detached, and
    again over its period-doubled search's closed isolas when time integration keeps none.
    Default 3: without harmonic_checks, on the default scene time integration leaves the
    largest stable amplitude of the 3 Omega = omega_1 isola, at its end next to a fold (DLFT
    878 rad/s, RL 883 rad/s), for a state of half its amplitude; DLFT's third try is kept,
    none of RL's three. With them both are kept at the first march.
    harmonic_checks: most points per primary, isola or period-doubled point (per doubled
    branch) checked before they are marched (hbm.stability.convergence.check_harmonics:
    solved again with 2 N_h, and for RL stable there too); a point that fails is not
    marched and its stable stretch is ruled out, as for a march that leaves. 0: none. A
    check costs 2-9 s at N_h = 40 on rotor 67 against ~40 s for a march; default 6: the
    default scene's RL isola point is the fifth choice.
    dt: the step of these marches, s (Carpenter's central differences, whatever [ti] scheme:
    the verdicts, stays or leaves over 100 periods, were measured with it; the exponential
    scheme's step is chosen on the sweep's classes and amplitudes). Default 1e-7.
    dt_refinement: when time integration with dt leaves a stable point for anything but
    the friction lock, the point is marched again with dt / dt_refinement before the verdict
    counts (1: never). Default 4: on the default rotor 67 scene time integration leaves the
    DLFT isola point at 823.3 rad/s (|mu| = 0.984 with N_h = 40 and 0.989 with 80, RL stable
    there too) with dt = 1e-7 and 5e-8 s and stays with 2.5e-8 and 1.25e-8 s; the second
    march costs dt_refinement first ones.
    """

    n_periods: int = 100
    n_candidates: int = 24
    n_scan: int = 24
    pd_points: int = 40
    pd_tries: int = 4
    primary_tries: int = 3
    isola_tries: int = 3
    harmonic_checks: int = 6
    dt: float = 1e-7
    dt_refinement: int = 4

    def __post_init__(self):
        for name, least, note in (("n_periods", 3, ""), ("n_candidates", 1, ""), ("n_scan", 2, ""), ("pd_points", 2, ""),
                                  ("pd_tries", 1, ""), ("primary_tries", 1, ""), ("isola_tries", 1, ""),
                                  ("harmonic_checks", 0, "0: none"), ("dt_refinement", 1, "1: no second march")):
            check_option(name, getattr(self, name), least, integer=True, note=note)
        check_option("dt", self.dt, 0, low_open=True, unit="s")


#: Contact schemes of the time integration (hbm.ti.march): the forward-increment Lagrange
#: multipliers on the full ROM, or the massless-boundary model.
TI_SCHEMES = ("carpenter", "exponential", "massless")


@dataclass(frozen=True)
class TimeIntegrationOptions:
    """Time-integration reference.

    scheme: "exponential" (every ROM mode, its free motion over a step exact, forward-
    increment Lagrange multipliers: no stability limit), "carpenter" (the same multipliers
    with central differences: dt below 2 / w_max) or "massless" (modes above
    massless_cutoff replaced by their static response: a massless boundary, a static contact
    projection and a step set by the kept modes; a different model, see
    hbm.ti.march.massless_system). Default "exponential" with dt = 1e-6 s: on the default
    rotor 67 sweep it keeps more of Carpenter-at-5e-8's classes than Carpenter at 1e-7 does
    (158 and 156 of 161), the periodic LE amplitudes within 0.33 % (median 1.7e-4), for about
    a sixth of Carpenter's per-speed CPU time at 1e-7 (0.15 and 0.18, one sweep each); a
    step should not exceed half the period of the ROM's highest mode
    (hbm.ti.march.EXPONENTIAL_STEP_FRACTION: 1.07e-6 s there; at 2e-6 s 155 classes and
    amplitudes to 4.7 %). Carpenter is the reference; the massless model's
    static projection wedges the tip into the casing with friction (mu = 0.15, at the
    contact set's friction-lock limit: contact at every step, amplitude growing as dt
    shrinks: 2 to 10 times Carpenter's at dt = 1e-6); without friction it agrees with
    Carpenter to 1 to 20 % at 30 times fewer steps.
    dt: time step, s (shrunk so that revolutions, casing periods and samples fall on steps).
    massless_cutoff: highest ROM eigenfrequency kept by the massless scheme, rad/s. Default
    9e4: above what the HBM resolves at N_h = 40 (40 Omega_max = 8e4 rad/s), below the
    first mode that carries most of the tip's radial compliance (1.1e5 rad/s on the default
    scene's ROM, 9.3e4 on the coarse one): past it the static contact stiffness, and with it
    the stable step, jumps by 30 times.
    n_revolutions: revolutions simulated per Omega at most (from rest).
    n_keep: last revolutions kept for amplitude and periodicity (< n_revolutions: the first
    revolution from rest is never steady).
    stop_when_settled: stop before n_revolutions once the response has provably settled on a
    periodic orbit (hbm.ti.settle); false: always n_revolutions.
    settle_rtol: the largest transient (relative to each node's range over the window) that
    may remain when a march stops early, -. Default 1e-3: ten times below the 1 % on the
    LE amplitude at which two schemes are called equal and below the discretisation error
    at dt = 1e-7 (0.07 to 5 %); against 200 revolutions every periodic speed of the default
    rotor 67 sweep keeps its class and its LE amplitude to 3e-4 (benchmarks/bench_ti.py
    --full-sweep --compare-full), for 9 % fewer revolutions and 18 % less CPU time than 1e-4.
    omega_min, omega_max, n_omega: the sweep grid of Omega, rad/s (each speed starts from rest).
    samples_per_revolution: rate of the kept (downsampled) signals, per revolution.
    periodicity_rtol: mismatch accepted between Poincare sections one period apart,
    relative to the signal's range, -. max_order: largest subharmonic order nu = Omega / omega
    still called periodic, -.
    """

    scheme: str = "exponential"
    dt: float = 1e-6
    massless_cutoff: float = 9.0e4
    n_revolutions: int = 200
    n_keep: int = 20
    stop_when_settled: bool = True
    settle_rtol: float = 1e-3
    omega_min: float = 400.0
    omega_max: float = 2000.0
    n_omega: int = 161
    samples_per_revolution: int = 256
    periodicity_rtol: float = 1e-2
    max_order: float = 10.0

    def __post_init__(self):
        if self.scheme not in TI_SCHEMES:
            raise ValueError(f"unknown time-integration scheme '{self.scheme}'; known: {', '.join(TI_SCHEMES)}")
        check_option("dt", self.dt, 0, low_open=True, unit="s")
        check_option("massless_cutoff", self.massless_cutoff, 0, low_open=True, unit="rad/s")
        check_option("n_revolutions", self.n_revolutions, 2, integer=True)
        check_option("n_keep", self.n_keep, 1, integer=True)
        check_flag("stop_when_settled", self.stop_when_settled)
        if not 0 < self.n_keep < self.n_revolutions:
            raise ValueError(f"need 0 < n_keep < n_revolutions (the first revolution from rest is never "
                             f"steady), got n_keep = {self.n_keep}, n_revolutions = {self.n_revolutions}")
        for k in ("omega_min", "omega_max"):
            check_option(k, getattr(self, k), 0, low_open=True, unit="rad/s")
        if not 0 < self.omega_min <= self.omega_max:
            raise ValueError(f"need 0 < omega_min <= omega_max, got {self.omega_min}, {self.omega_max}")
        check_option("n_omega", self.n_omega, 1, integer=True)
        check_option("samples_per_revolution", self.samples_per_revolution, 1, integer=True)
        if not 0 < self.periodicity_rtol < 1:
            raise ValueError(f"periodicity_rtol must be in (0, 1), got {self.periodicity_rtol}")
        if not 0 < self.settle_rtol < self.periodicity_rtol:
            raise ValueError(f"settle_rtol must be in (0, periodicity_rtol = {self.periodicity_rtol}), "
                             f"got {self.settle_rtol}")
        check_option("max_order", self.max_order, 1)

    def classified_order(self, n_lobes: int) -> float:
        """The largest order nu = Omega / omega the sweep can call periodic, -: max_order, or less
        where the kept window (n_keep revolutions: n_keep n_l + 1 Poincare sections) cannot show a
        period twice (hbm.ti.periodicity.classify_period tries p <= n_keep n_l / 2 casing periods).
        What "no periodicity" means on a figure: no period up to this order."""
        p = min(math.floor(self.max_order * n_lobes + 1e-9), self.n_keep * n_lobes // 2)
        return p / n_lobes

    @property
    def omegas(self):
        """The sweep grid, (n_omega,), rad/s: the one definition (an interrupted sweep's speeds
        on disk are matched against it to the bit)."""
        import numpy as np

        return np.linspace(self.omega_min, self.omega_max, self.n_omega)
