"""Stage ti: the time-integration sweep from rest over the speed grid (ti.h5)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hbm.ti.sweep import SweepResult
from pipelines import artifacts as art
from pipelines.stages.base import Context, Figure, Output, Stage
from pipelines.stages.rom import read_rom

TI = Output("ti.h5")


def _compute(ctx: Context, outputs) -> None:
    """Under `mpirun -n N` the sweep shares its speeds among the ranks (hbm.ti.sweep) and
    rank 0 writes ti.h5."""
    from hbm.ti.sweep import sweep
    from pipelines.parallel import on_root, world

    scene = ctx.scene
    rom = read_rom(ctx.out)
    with ctx.progress.step("ti sweep", scene.ti.n_omega) as update:
        result = sweep(rom, scene.casing, scene.contact, scene.ti)
        update(completed=scene.ti.n_omega)

    def write():
        art.write_artifact(ctx.out / TI.file, TiArtifact(result), **ctx.provenance(TI, "ti"))
        counts = np.bincount(result.period_class.astype(int), minlength=4)
        ctx.log(f"  {len(result.omega)} speeds; classes 2W/W/sub/none: {counts[:4].tolist()}; "
                f"median {np.median(result.cpu_time):.1f} s per speed")

    on_root(world(), write)


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
                  omega_range=(ctx.scene.ti.omega_min, ctx.scene.ti.omega_max))


SWEEP_FIGURE = Figure("ti_sweep", files=lambda scene: ("ti_sweep.png",), depends=("ti.omega_min", "ti.omega_max"),
                      inputs=lambda scene: (TI.file,), draw=draw_sweep)

# only mu of [contact]: the sweep's contact is exact (Lagrange multipliers), not DLFT or RL
STAGE = Stage("ti", depends=("casing", "contact.mu", "ti"), upstream=("rom",), outputs=lambda scene: (TI,),
              compute=_compute, figures=(SWEEP_FIGURE,), distributed=True)
