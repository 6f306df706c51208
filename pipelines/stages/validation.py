"""Stage validation: time integration marched from HBM solutions and compared with them
(validation.h5), a stage of its own so that changing N_h never reruns the TI sweep."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hbm.ti.validation import ValidationResult
from pipelines import artifacts as art
from pipelines.stages.base import Context, Figure, Output, Stage
from pipelines.stages.hbm import nfrc_output
from pipelines.stages.rom import read_rom

VALIDATION = Output("validation.h5")


@dataclass(frozen=True)
class ValidationArtifact:
    """What validation.h5 holds. method: the HBM treatment validated. point: index of the
    NFRC point marched from. result: hbm.ti.validation.ValidationResult."""

    method: str
    point: int = field(metadata={"unit": "1"})
    result: ValidationResult


def _compute(ctx: Context, outputs) -> None:
    from hbm.harmonic.residual import build_residual
    from hbm.ti.validation import validate_against_hbm
    from pipelines.branch_store import load_branch

    scene = ctx.scene
    method = scene.hbm.methods[0]
    stored = load_branch(ctx.out / nfrc_output(method).file)
    b = stored.branch
    amp = np.where(b.converged, stored.extras["le_amplitude"], -np.inf)
    i = int(np.argmax(amp))
    rom = read_rom(ctx.out)
    res = build_residual(rom, scene.casing, scene.contact, scene.hbm, method=method)
    u, omega = b.x[i], float(b.omega[i])
    with ctx.progress.step("validation", None) as update:
        update(f"{method.upper()}-HBM point at \u03a9 = {omega:.1f} rad/s, 100 periods")
        v = validate_against_hbm(rom, scene.casing, scene.contact, res.expand_harmonics(u, omega), omega,
                                 forces=res.signals(u, omega)["lam"], n_periods=100, dt=scene.ti.dt)
    art.write_artifact(ctx.out / VALIDATION.file, ValidationArtifact(method, i, v),
                       **ctx.provenance(VALIDATION, "validation"))
    ctx.log(f"  validation at Omega = {omega:.1f} rad/s ({method.upper()}-HBM peak): displacement error "
            f"LE {100 * v.displacement_error[0]:.2f} %, TE {100 * v.displacement_error[1]:.2f} %; "
            f"force error LE {100 * v.force_error[0]:.1f} %, TE {100 * v.force_error[1]:.1f} %")


def draw_validation(ctx: Context) -> None:
    from pipelines.figures import plot_time_signals

    a = art.read_artifact(ctx.out / VALIDATION.file, ValidationArtifact)
    v, m = a.result, a.method.upper()
    t = v.tau / v.omega
    fig = ctx.out / "figures"
    plot_time_signals(t, {f"{m}-HBM LE": 1e3 * v.hbm_displacement[:, 0], "TI LE": 1e3 * v.ti_displacement[:, 0],
                          f"{m}-HBM TE": 1e3 * v.hbm_displacement[:, 1], "TI TE": 1e3 * v.ti_displacement[:, 1]},
                      fig / "validation_displacement.png", "radial displacement (mm)")
    plot_time_signals(t, {f"{m}-HBM LE": v.hbm_force[:, 0], "TI LE": v.ti_force[:, 0],
                          f"{m}-HBM TE": v.hbm_force[:, 1], "TI TE": v.ti_force[:, 1]},
                      fig / "validation_force.png", "normal contact force (N)")


FIGURES = Figure("validation", files=lambda s: ("validation_displacement.png", "validation_force.png"),
                 depends=(), inputs=lambda s: (VALIDATION.file,), draw=draw_validation)

STAGE = Stage("validation", depends=("casing", "contact", "ti.dt", "hbm.methods"), upstream=("rom", "hbm"),
              outputs=lambda scene: (VALIDATION,) if scene.hbm.methods else (), compute=_compute,
              figures=(FIGURES,))
