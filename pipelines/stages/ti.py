"""Stage ti: the time-integration sweep from rest over the speed grid (ti.h5)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hbm.ti.sweep import SweepResult
from pipelines import artifacts as art
from pipelines.stages.base import Background, Context, Estimate, Figure, Output, Stage
from pipelines.stages.rom import read_rom, warn_friction_lock

TI = Output("ti.h5")


def massless_warning(scheme: str, mu: float, lock) -> str | None:
    """The warning for a massless-boundary sweep past the ROM's friction lock (lock: its
    rom.friction_lock.FrictionLock, or None), else None. There, where the tip stays in
    contact, the massless scheme settles on an amplitude inversely proportional to the step
    (on the coarse rotor 67 ROM 13.8, 7.1 and 3.3 times Carpenter's at dt = 1e-6, 2e-6 and
    5e-6 s, 1400 rad/s, mu = 0.15 > mu_set = 0.123; README): no answer converged in dt."""
    if scheme != "massless" or lock is None or not lock.warnings(mu):
        return None
    return (f"[ti] scheme = massless with friction mu = {mu:g} past the ROM's friction lock (mu_set = "
            f"{lock.mu_set:.3g}): where a node stays in contact the amplitude follows the step dt, not the "
            "physics; scheme = carpenter keeps the boundary's mass")


def step_lock_warning(scheme: str, mu: float, lock) -> str | None:
    """The warning for a Carpenter sweep whose friction is past its time step's own lock
    (lock: rom.friction_lock.lock_table of hbm.ti.march.step_compliance), else None. There
    the step's contact problem has no unique solution where the nodes it couples slide
    together: its active set can cycle to the cap (ti.h5's active_set_failures counts those
    steps) and the march can blow up. Set by the inverse mass's radial-tangential coupling,
    not by dt; far above the static mu_set on rotor 67 (README)."""
    if scheme not in ("carpenter", "exponential") or lock is None or mu < lock.mu_set:
        return None
    return (f"friction mu = {mu:g} >= {lock.mu_set:.3g}, where the time step's contact problem (radial "
            "compliance with the friction columns) stops being a P-matrix: steps in contact may have no "
            "unique multipliers (see active_set_failures in ti.h5)")


def exponential_step_warning(scheme: str, dt: float, system) -> str | None:
    """The warning for an exponential sweep whose step dt (s) exceeds half the period of the
    ROM's highest mode, pi / w_max of its modal system (hbm.ti.march.ModalSystem): the step
    within which that scheme was measured as accurate as Carpenter at 1e-7 s
    (hbm.ti.march.EXPONENTIAL_STEP_FRACTION times the central-difference limit 2 / w_max),
    else None. The scheme is stable at any step, so nothing else would tell a user whose
    blade is stiffer than rotor 67 that the default step (1e-6 s) is too coarse for it."""
    from hbm.ti.march import EXPONENTIAL_STEP_FRACTION, critical_time_step

    if scheme != "exponential":
        return None
    limit = EXPONENTIAL_STEP_FRACTION * critical_time_step(system)
    if dt <= limit:
        return None
    return (f"the exponential scheme's step dt = {dt:g} s is {dt / limit:.2f} times half the period of this ROM's "
            f"highest mode, pi / w_max = {limit:.3g} s; its sweeps were as accurate as Carpenter at 1e-7 s only "
            f"within it (README, *Time integration*): above, contact-heavy speeds can change class; "
            f"[ti] dt <= {limit:.3g} s keeps within it")


class SweepPartial:
    """ti.partial.h5: each speed of the sweep as it ends, so that an interrupted sweep goes
    on from the speeds it finished (the NFRCs' and the isola search's partial files do the
    same). One group per speed, `speeds/III` (III its index in the scene's grid) with the
    hbm.ti.sweep.SpeedResponse fields as datasets and `complete` written last; the file is
    reopened for each speed, so a kill leaves at most that speed cut, and it is dropped on
    reading. Root attributes: inputs_hash (ti.h5's), n_speeds (complete speeds, for what an
    interrupted run says it kept).

    Under `mpirun` every rank keeps its own speeds, rank r > 0 in ti.rR.partial.h5 beside it
    (one writer per HDF5 file), and a resumed run, on any number of ranks or none, takes the
    speeds of all of them (`rank`: this process's rank, 0 without MPI)."""

    def __init__(self, path, inputs_hash: str, rank: int = 0):
        from pipelines.branch_store import rank_partial_path

        self.path, self.hash = path, inputs_hash
        self.own = rank_partial_path(path, rank)

    def files(self) -> list:
        """The partial files of this sweep on disk: rank 0's first, then the other ranks'."""
        from pipelines.branch_store import partial_files

        return partial_files(self.path)

    def resume(self, omegas: np.ndarray) -> dict:
        """{index: SpeedResponse} kept by an interrupted sweep of these inputs over `omegas`
        ((n_omega,), rad/s), from every rank's file; {} from a file that holds other inputs
        or cannot be read."""
        found = {}
        for path in self.files():
            found.update(self._read(path, omegas))
        return found

    def _read(self, path, omegas: np.ndarray) -> dict:
        import h5py

        from hbm.ti.sweep import SpeedResponse

        if art.read_attrs(path).get("inputs_hash") != self.hash:
            return {}
        names = [f.name for f in SpeedResponse.__dataclass_fields__.values()]
        found = {}
        try:
            with h5py.File(path, "r") as h5:
                for key, g in h5.get("speeds", {}).items():
                    i = int(key)
                    if not g.attrs.get("complete", 0) or i >= len(omegas) or g["omega"][()] != omegas[i]:
                        continue
                    found[i] = SpeedResponse(**{k: (g[k][()] if k in g else None) for k in names})
        except (OSError, KeyError, ValueError):
            return {}
        return found

    def remove(self) -> None:
        """Every rank's file (once ti.h5 holds every speed)."""
        for p in self.files():
            p.unlink(missing_ok=True)

    def speed(self, i: int, response) -> None:
        """Keep speed i's SpeedResponse (in this rank's file)."""
        from dataclasses import fields

        fresh = not self.own.is_file() or art.read_attrs(self.own).get("inputs_hash") != self.hash
        with art.open_in_place(self.own, "w" if fresh else "a") as h5:
            if fresh:
                h5.attrs["inputs_hash"] = self.hash
            speeds = h5.require_group("speeds")
            name = f"{i:03d}"
            if name in speeds:
                del speeds[name]
            g = speeds.create_group(name)
            for f in fields(response):
                value = getattr(response, f.name)
                if value is not None:
                    g.create_dataset(f.name, data=value).attrs["unit"] = f.metadata["unit"]
            g.attrs["complete"] = 1  # last: the speed counts once all of it is written
            h5.attrs["n_speeds"] = sum(int(s.attrs.get("complete", 0)) for s in speeds.values())


def _partial(ctx: Context, rank: int = 0) -> SweepPartial:
    from pipelines.branch_store import partial_path

    return SweepPartial(partial_path(ctx.out / TI.file), ctx.hashes[TI.file], rank)


def _resumed(ctx: Context, partial: SweepPartial) -> dict:
    t = ctx.scene.ti
    for path in partial.files():
        unreadable = art.read_failure(path)
        if unreadable:
            ctx.progress.warn(f"{path.name} cannot be read ({unreadable}): its speeds are marched again")
    done = partial.resume(t.omegas)
    if done:
        ctx.log(f"  resuming from {len(done)} of {t.n_omega} speeds on disk "
                f"({', '.join(p.name for p in partial.files())})")
    return done


def _compute(ctx: Context, outputs) -> None:
    """Under `mpirun -n N` the sweep shares its speeds among the ranks (hbm.ti.sweep), each
    keeps its own speeds as they end (SweepPartial), and rank 0 writes ti.h5."""
    from hbm.ti.sweep import sweep
    from pipelines.parallel import on_root, world

    scene = ctx.scene
    rom = read_rom(ctx.out)
    _warn(ctx, rom)
    comm = world()
    partial = _partial(ctx, 0 if comm is None else comm.rank)
    # rank 0 alone reads the partial files (HDF5 locks a file one process writes); every
    # rank then writes its own
    done = on_root(comm, lambda: _resumed(ctx, partial))
    with ctx.progress.step("ti sweep", scene.ti.n_omega) as update:
        update(completed=len(done))
        result = sweep(rom, scene.casing, scene.contact, scene.ti, on_point=lambda n, total: update(completed=n),
                       done=done, on_speed=partial.speed)
    on_root(comm, lambda: _write(ctx, result, partial))


def _start(ctx: Context, outputs, cores: int) -> Background:
    """The sweep on a pool of one worker per core, started beside the NFRCs with `cores`
    cores and the others as the NFRC processes end (hbm.ti.sweep.SweepRun): the core the
    shorter NFRC frees marches speeds while the longer one runs."""
    from hbm.ti.sweep import SweepRun

    scene = ctx.scene
    rom = read_rom(ctx.out)
    live = []  # the live line's update, once the stage's turn has come

    def on_point(done: int, total: int) -> None:
        if live:
            live[0](completed=done)

    partial = _partial(ctx)
    done = _resumed(ctx, partial)
    run = SweepRun(rom, scene.casing, scene.contact, scene.ti, cores=cores, on_point=on_point, done=done,
                   on_speed=partial.speed)
    try:
        _warn(ctx, rom)
    except BaseException:
        run.cancel()
        raise

    def finish() -> None:
        ctx.log(f"  {run.done} of {len(run.omegas)} speeds done beside the stage before")
        with ctx.progress.step("ti sweep", len(run.omegas)) as update:
            live.append(update)
            update(completed=run.done)
            result = run.result()
        _write(ctx, result, partial)

    return Background(lend=run.lend, finish=finish, cancel=run.cancel,
                      status=lambda: f"ti: {run.done}/{len(run.omegas)} speeds")


def _warn(ctx: Context, rom) -> None:
    warn_friction_lock(ctx, rom)
    scene = ctx.scene
    line = massless_warning(scene.ti.scheme, scene.contact.mu, rom.friction_lock)
    if line:
        ctx.log("  WARNING: " + line)
    if scene.ti.scheme in ("carpenter", "exponential"):
        from hbm.ti.march import rom_modal_system, step_compliance
        from rom.friction_lock import lock_table

        system = rom_modal_system(rom)
        line = exponential_step_warning(scene.ti.scheme, scene.ti.dt, system)
        if line:
            ctx.log("  WARNING: " + line)
        lock = lock_table(*step_compliance(system, scene.ti.dt, scene.ti.scheme == "exponential"), rom.rotation)
        ctx.log(f"  contact step (dt = {scene.ti.dt:g} s): unique multipliers up to mu = {lock.mu_set:.3g} "
                f"(mu = {scene.contact.mu:g})")
        line = step_lock_warning(scene.ti.scheme, scene.contact.mu, lock)
        if line:
            ctx.log("  WARNING: " + line)


def _write(ctx: Context, result, partial: SweepPartial) -> None:
    from hbm.ti.periodicity import PeriodClass

    scene = ctx.scene
    art.write_artifact(ctx.out / TI.file, TiArtifact(result), **ctx.provenance(TI, "ti"))
    partial.remove()  # ti.h5 holds every speed now
    n_l = scene.casing.n_lobes
    counts = np.bincount(result.period_class.astype(int), minlength=len(PeriodClass))
    ctx.log(f"  {len(result.omega)} speeds; classes: "
            + ", ".join(f"{c.label(n_l, scene.ti.classified_order(n_l))} {counts[c]}" for c in PeriodClass if counts[c])
            + f"; median {np.median(result.cpu_time):.1f} s per speed")
    line = capped_contact_warning(result)
    if line:
        ctx.log("  WARNING: " + line)
    line = explicit_direction_warning(result)
    if line:
        ctx.log(("  WARNING: " if fallback_shares(result).max() >= FALLBACK_SHARE_WARNING else "  note: ") + line)


def capped_contact_warning(result) -> str:
    """One line naming the speeds where the contact solve hit its iteration cap at some step
    (SweepResult.active_set_failures > 0: that step kept a clipped iterate, so its contact
    forces, and the response after it, are approximate); "" when there is none."""
    failures = result.active_set_failures
    if failures is None:
        return ""
    bad = np.flatnonzero(np.asarray(failures) > 0)
    if not bad.size:
        return ""
    shown = ", ".join(f"{result.omega[i]:.0f} ({int(failures[i])} steps)" for i in bad[:5])
    return (f"the contact solve hit its iteration cap at {bad.size} speed(s), rad/s: {shown}"
            f"{' ...' if bad.size > 5 else ''}; those steps kept an approximate contact force "
            "(ti.h5: sweep/active_set_failures)")


#: The share of a speed's contact steps taking the prediction's direction from which the log
#: calls it a WARNING rather than a note. On the default scene's sweep the shares are 1e-7 to
#: 4e-5 (one to a few dozen steps) at speeds whose periodic LE amplitude is Carpenter's at
#: 5e-8 s to 1.5e-4 (670, 1480, 1510 rad/s), and 0.1 to 2 % at 640-650 and 1240-1290 rad/s
#: (benchmarks/README.md, *Time integration*).
FALLBACK_SHARE_WARNING = 1e-3


def fallback_shares(result) -> np.ndarray:
    """Each speed's contact steps that took the prediction's sliding direction, as a share of
    its contact steps (SweepResult.explicit_direction_steps over contact_fraction times the
    steps marched), (n_omega,), -; zeros where the count is unknown (None, or -1)."""
    steps = result.explicit_direction_steps
    if steps is None:
        return np.zeros(len(result.omega))
    contact = np.maximum(np.asarray(result.contact_fraction) * np.asarray(result.revolutions) * 2.0 * np.pi
                         / (np.asarray(result.omega) * np.asarray(result.dt)), 1.0)
    return np.maximum(np.asarray(steps), 0) / contact


def explicit_direction_warning(result) -> str:
    """One line naming the speeds where some contact step's friction direction did not settle
    (SweepResult.explicit_direction_steps > 0: a sliding reversal within the step, or a node
    dragged past its friction lock): those steps took the prediction's direction, whose error
    is O(dt). The speeds come by their share of such steps among their contact steps
    (fallback_shares), largest first: one step in ten million is not 2 % of them. "" when
    there is none."""
    share = fallback_shares(result)
    bad = np.flatnonzero(share > 0)
    if not bad.size:
        return ""
    steps = result.explicit_direction_steps
    bad = bad[np.argsort(-share[bad], kind="stable")]
    shown = ", ".join(f"{result.omega[i]:.0f} rad/s {100 * share[i]:.2g} % ({int(steps[i])} steps)" for i in bad[:5])
    return (f"the friction's sliding direction did not settle at {bad.size} speed(s); share of a speed's contact "
            f"steps, largest first: {shown}{' ...' if bad.size > 5 else ''}; those steps took the prediction's "
            "direction, an O(dt) error (ti.h5: sweep/explicit_direction_steps)")


@dataclass(frozen=True)
class TiArtifact:
    """What ti.h5 holds: the sweep (hbm.ti.sweep.SweepResult) under the group `sweep`."""

    sweep: SweepResult


def read_sweep(out):
    """The SweepResult of an output folder."""
    return art.read_artifact(out / TI.file, TiArtifact).sweep


#: legend entry of the speeds sweep_points flags
FLAGGED_LABEL = (f"TI: friction direction of the prediction\nin \u2265 {FALLBACK_SHARE_WARNING:.1%} of "
                 "contact steps")


def sweep_points(out):
    """The sweep's points for the figures that draw them: (omega (p,) rad/s, LE amplitude (p,)
    m, period_class (p,) int, flagged (p,) bool), or None without ti.h5. flagged: the speeds
    the fallback WARNING names (share >= FALLBACK_SHARE_WARNING), ringed in the figures: on the
    coarse rotor 67 scene, past its ROM's friction lock, they are the speeds whose tip drifts."""
    if not (out / TI.file).is_file():
        return None
    s = read_sweep(out)
    return s.omega, s.amplitude, s.period_class, fallback_shares(s) >= FALLBACK_SHARE_WARNING


def draw_sweep(ctx: Context) -> None:
    from pipelines.figures import plot_ti_sweep

    omega, amplitude, classes, flagged = sweep_points(ctx.out)
    plot_ti_sweep(omega, amplitude, classes, ctx.out / "figures" / "ti_sweep.png",
                  omega_range=(ctx.scene.ti.omega_min, ctx.scene.ti.omega_max), n_lobes=ctx.scene.casing.n_lobes,
                  max_order=ctx.scene.ti.classified_order(ctx.scene.casing.n_lobes), flagged=flagged,
                  flagged_label=FLAGGED_LABEL)


SWEEP_FIGURE = Figure("ti_sweep", files=lambda scene: ("ti_sweep.png",),
                      depends=("ti.omega_min", "ti.omega_max", "casing.n_lobes", "ti.max_order", "ti.n_keep"),
                      inputs=lambda scene: (TI.file,), draw=draw_sweep)

def _estimate(scene, out, outputs) -> Estimate:
    # steps over the grid (each speed from rest, n_revolutions at most), spread over the cores.
    # CPU time = STEP_SECONDS per step plus REVOLUTION_SECONDS per revolution, both of the full
    # n_revolutions (early stops included in the fit): a step costs more the longer it is (more
    # passes per contact step), which the per-revolution term carries. Fitted to whole rotor 67
    # sweeps on an AMD EPYC (Zen 3) host (default ROM, exponential 2.5e-7 to 4e-6 s, Carpenter
    # 5e-8 and 1e-7 s): within 25 % of each, where one cost per step was off 4.5 times at
    # 1e-6 s. Its speeds settle in ~70 % of the revolutions; rotor 37's coarse ROM settles in
    # 36 % and its sweeps take half the estimate.
    # The grid itself is built only while it is small: n_omega is the user's (a scene may say
    # 1e12 or 2**63 - 1, which np.linspace cannot hold or index), and the estimate must name
    # it, not fail on it. Past GRID_SUM_MAX speeds, sum(1 / Omega) over the evenly spaced grid
    # is n_omega times the mean of 1 / Omega over [omega_min, omega_max] (the integral mean,
    # ln(max / min) / (max - min)); the two differ by O(1 / n_omega), < 1e-5 there.
    from pipelines.guard import count

    t = scene.ti
    if t.n_omega <= GRID_SUM_MAX:
        inverse = float(np.sum(1.0 / t.omegas))
    elif t.omega_max > t.omega_min:
        inverse = t.n_omega * np.log(t.omega_max / t.omega_min) / (t.omega_max - t.omega_min)
    else:
        inverse = t.n_omega / t.omega_min
    steps = t.n_revolutions * 2 * np.pi / t.dt * inverse
    cores = len(__import__("os").sched_getaffinity(0))
    disk = t.n_omega * (t.n_keep * t.samples_per_revolution * 4 + 64) * 8.0
    # memory: ~0.3 GB per worker, and the sweep's result (hbm.ti.sweep.SweepResult, every
    # speed's kept signals, what ti.h5 holds) gathered in this process before ti.h5 is written
    return Estimate(size=f"{count(t.n_omega)} speeds, {steps:.3g} steps", memory=0.3e9 * min(cores, t.n_omega) + disk,
                    seconds=(STEP_SECONDS * steps + REVOLUTION_SECONDS * t.n_omega * t.n_revolutions)
                    / min(cores, t.n_omega), disk=disk,
                    advice="lower [ti] n_omega or n_revolutions, or raise dt")


#: The sweep's estimated CPU time per step (s) and per revolution (s), see _estimate.
STEP_SECONDS, REVOLUTION_SECONDS = 290e-9, 0.8e-3

#: Most speeds for which _estimate sums over the grid itself (an 8 MB array, ~ms).
GRID_SUM_MAX = 1_000_000


# only mu of [contact]: the sweep's contact is exact (Lagrange multipliers), not DLFT or RL
STAGE = Stage("ti", depends=("casing", "contact.mu", "ti"), upstream=("rom",), outputs=lambda scene: (TI,),
              compute=_compute, figures=(SWEEP_FIGURE,), estimate=_estimate, distributed=True, start=_start)
