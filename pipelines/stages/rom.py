"""Stage rom: Craig-Bampton reduction on the contact nodes (rom.h5)."""
from __future__ import annotations

import numpy as np

from pipelines import artifacts as art
from pipelines.stages.base import Context, Estimate, Output, Stage
from pipelines.stages.fem import fem_bytes, read_fem
from pipelines.stages.mesh import coarser_mesh, node_count, nodes_text, read_mesh

ROM = Output("rom.h5")


def read_rom(out, with_recovery: bool = False):
    """The RomModel of an output folder (rom.model.load_rom: refuses a file with a missing
    field; the large recovery matrix only when asked)."""
    from rom.model import load_rom

    path = out / ROM.file
    if not path.is_file():
        raise art.ArtifactError(f"artifact not found: {path}")
    return load_rom(path, with_recovery=with_recovery)


def warn_friction_lock(ctx: Context, rom) -> None:
    """Log the friction-lock warnings of the ROM's table for the scene's mu (the stages that
    use mu call this: the table in rom.h5 does not depend on mu), once a run."""
    if rom.friction_lock is not None:
        for line in rom.friction_lock.warnings(ctx.scene.contact.mu):
            ctx.progress.log_once("  WARNING: " + line)


def past_friction_lock(mu: float, rom) -> bool:
    """Whether mu is at or above the ROM's contact-set limit mu_set (rom.friction_lock; False
    without one), where a node held on the casing is the friction lock, a state of the model
    (the validation stage's marches in permanent contact, the isola search's branches)."""
    lock = getattr(rom, "friction_lock", None)
    return lock is not None and mu >= lock.mu_set


def _compute(ctx: Context, outputs) -> None:
    from rom.craig_bampton import build_craig_bampton

    scene = ctx.scene
    rom = build_craig_bampton(read_fem(ctx.out), read_mesh(ctx.out), scene.rom, rotation=scene.blade.rotation)
    art.write_artifact(ctx.out / ROM.file, rom, **ctx.provenance(ROM, "rom"))
    k = min(6, len(rom.full_frequencies))
    err = (rom.frequencies[:k] - rom.full_frequencies[:k]) / rom.full_frequencies[:k]
    ctx.log(f"  {rom.n_dof} dof ({3 * rom.n_boundary} boundary + {rom.n_dof - 3 * rom.n_boundary} modal)")
    ctx.log("  ROM frequencies, Hz:  " + " ".join(f"{f:.2f}" for f in rom.frequencies[:k] / (2 * np.pi)))
    ctx.log("  error vs full model:  " + " ".join(f"{100 * e:+.3f}%" for e in err))
    how = "(le-leads: the LE leads)" if scene.blade.rotation == "le-leads" else "(stated in the scene)"
    ctx.log(f"  rotation: s = {rom.rotation:+d} {how}")
    # the table in rom.h5 does not depend on mu (changing mu must not rerun the ROM); the
    # verdict for the scene's mu is printed here, and by the stages that use mu when the ROM was reused
    for line in rom.friction_lock.report(scene.contact.mu):
        ctx.log("  " + line)
    warn_friction_lock(ctx, rom)


def _estimate(scene, out, outputs) -> Estimate | None:
    # reads fem.h5 whole (K, M, the modes); writes the float32 recovery matrix (dof x ROM dof)
    n, exact = node_count(scene, out)
    n_rom = 3 * scene.n_contact_nodes + scene.rom.n_fixed_modes
    return Estimate(size=nodes_text(n, exact), memory=0.2e9 + 1.3 * fem_bytes(scene, n), seconds=2.0 + 5e-5 * n,
                    disk=3 * n * n_rom * 4.0, advice=coarser_mesh(scene))


# blade.rotation: the ROM carries the sense of rotation (and its friction-lock table)
STAGE = Stage("rom", depends=("rom", "blade.rotation"), upstream=("fem", "mesh"), outputs=lambda scene: (ROM,),
              compute=_compute, estimate=_estimate)
