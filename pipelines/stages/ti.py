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


def _compute(ctx: Context, outputs) -> None:
    """Under `mpirun -n N` the sweep shares its speeds among the ranks (hbm.ti.sweep) and
    rank 0 writes ti.h5."""
    from hbm.ti.sweep import sweep
    from pipelines.parallel import on_root, world

    scene = ctx.scene
    rom = read_rom(ctx.out)
    _warn(ctx, rom)
    with ctx.progress.step("ti sweep", scene.ti.n_omega) as update:
        result = sweep(rom, scene.casing, scene.contact, scene.ti, on_point=lambda done, total: update(completed=done))
    on_root(world(), lambda: _write(ctx, result))


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

    run = SweepRun(rom, scene.casing, scene.contact, scene.ti, cores=cores, on_point=on_point)
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
        _write(ctx, result)

    return Background(lend=run.lend, finish=finish, cancel=run.cancel,
                      status=lambda: f"ti: {run.done}/{len(run.omegas)} speeds")


def _warn(ctx: Context, rom) -> None:
    warn_friction_lock(ctx, rom)
    line = massless_warning(ctx.scene.ti.scheme, ctx.scene.contact.mu, rom.friction_lock)
    if line:
        ctx.log("  WARNING: " + line)


def _write(ctx: Context, result) -> None:
    from hbm.ti.periodicity import PeriodClass

    scene = ctx.scene
    art.write_artifact(ctx.out / TI.file, TiArtifact(result), **ctx.provenance(TI, "ti"))
    n_l = scene.casing.n_lobes
    counts = np.bincount(result.period_class.astype(int), minlength=len(PeriodClass))
    ctx.log(f"  {len(result.omega)} speeds; classes: "
            + ", ".join(f"{c.label(n_l, scene.ti.max_order)} {counts[c]}" for c in PeriodClass if counts[c])
            + f"; median {np.median(result.cpu_time):.1f} s per speed")


@dataclass(frozen=True)
class TiArtifact:
    """What ti.h5 holds: the sweep (hbm.ti.sweep.SweepResult) under the group `sweep`."""

    sweep: SweepResult


def read_sweep(out):
    """The SweepResult of an output folder."""
    return art.read_artifact(out / TI.file, TiArtifact).sweep


def draw_sweep(ctx: Context) -> None:
    from pipelines.figures import plot_ti_sweep

    s = read_sweep(ctx.out)
    plot_ti_sweep(s.omega, s.amplitude, s.period_class, ctx.out / "figures" / "ti_sweep.png",
                  omega_range=(ctx.scene.ti.omega_min, ctx.scene.ti.omega_max), n_lobes=ctx.scene.casing.n_lobes)


SWEEP_FIGURE = Figure("ti_sweep", files=lambda scene: ("ti_sweep.png",),
                      depends=("ti.omega_min", "ti.omega_max", "casing.n_lobes"),
                      inputs=lambda scene: (TI.file,), draw=draw_sweep)

def _estimate(scene, out, outputs) -> Estimate:
    # central-difference steps over the grid (each speed from rest, 200 revolutions at most):
    # ~110 ns per step without contact, about 2.5 times more in contact (README, bench_ti);
    # over the default scene's whole sweep, early stops included, 110 ns per step of the full
    # 200 revolutions, idle machine, spread over the cores
    t = scene.ti
    omegas = np.linspace(t.omega_min, t.omega_max, t.n_omega)
    steps = float(np.sum(t.n_revolutions * 2 * np.pi / (omegas * t.dt)))
    cores = len(__import__("os").sched_getaffinity(0))
    return Estimate(size=f"{t.n_omega} speeds, {steps:.3g} steps", memory=0.3e9 * min(cores, t.n_omega),
                    seconds=110e-9 * steps / min(cores, t.n_omega),
                    disk=t.n_omega * (t.n_keep * t.samples_per_revolution * 4 + 64) * 8.0,
                    advice="lower [ti] n_omega or n_revolutions, or raise dt")


# only mu of [contact]: the sweep's contact is exact (Lagrange multipliers), not DLFT or RL
STAGE = Stage("ti", depends=("casing", "contact.mu", "ti"), upstream=("rom",), outputs=lambda scene: (TI,),
              compute=_compute, figures=(SWEEP_FIGURE,), estimate=_estimate, distributed=True, start=_start)
