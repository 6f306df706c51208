"""Stage orchestration: the only place that knows file names and the order of stages.

Each stage reads the previous stage's artifact (never another stage's objects in
memory), calls its package, and writes its own artifact atomically. A stage whose
artifact was made from exactly the same inputs (scene sections it depends on, the
upstream artifact, the geometry file's content) is skipped.
"""
from __future__ import annotations

import dataclasses
import hashlib
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from hbm.ti.sweep import SweepResult
from hbm.ti.validation import ValidationResult
from pipelines import artifacts as art

STAGES = ("mesh", "fem", "rom", "hbm", "ti")


@dataclass(frozen=True)
class Stage:
    """name: stage name. sections: scene sections it depends on. upstream: stage it reads.
    outputs: artifact file names in the output folder. run: (scene, out, inputs_hash) -> None."""

    name: str
    sections: tuple[str, ...]
    upstream: tuple[str, ...]
    outputs: Callable[[object], tuple[str, ...]]
    run: Callable[[object, Path, str], None]
    extra: Callable[[object], str] = lambda scene: ""


def _file_hash(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def inputs_hash(scene, out: Path, stage: Stage) -> str:
    """Hash of exactly what `stage` depends on."""
    h = hashlib.sha256(scene.section_hash(*stage.sections).encode())
    h.update(stage.extra(scene).encode())
    if stage.name == "mesh":
        geometry = scene.resolve(scene.blade.geometry)
        if not geometry.is_file():
            raise FileNotFoundError(f"geometry file not found: {geometry} (from [blade] geometry in {scene.path})")
        h.update(_file_hash(geometry).encode())
    for upstream in stage.upstream:
        for name in REGISTRY[upstream].outputs(scene):
            h.update(art.read_attrs(out / name).get("inputs_hash", "missing").encode())
    return h.hexdigest()


# --- mesh ------------------------------------------------------------------------
def _run_mesh(scene, out: Path, h: str):
    from mesh.blade import mesh_blade

    result = mesh_blade(scene.blade, scene.mesh, scene.resolve(scene.blade.geometry))
    art.write_artifact(out / "mesh.h5", result, stage="mesh", scene_text=scene.text, inputs_hash=h)
    print(f"  {result.n_nodes} nodes, {len(result.cells)} tet10 cells, volume {result.volume:.4e} m^3 "
          f"(section integral {result.reference_volume:.4e} m^3)")


def _read_mesh(out: Path):
    from mesh.model import BladeMesh

    return art.read_artifact(out / "mesh.h5", BladeMesh)


# --- fem ---------------------------------------------------------------------------
def _fem_options(scene):
    """The FEM stage also computes the ROM's fixed-interface modes from its factorisation of K."""
    import dataclasses

    n = max(scene.fem.n_fixed_interface_modes, scene.rom.n_fixed_modes)
    return dataclasses.replace(scene.fem, n_fixed_interface_modes=n)


def _run_fem(scene, out: Path, h: str):
    from fem.analysis import analyse_blade

    mesh = _read_mesh(out)
    timings: dict = {}
    result = analyse_blade(mesh, scene.material, _fem_options(scene), timings=timings)
    art.write_artifact(out / "fem.h5", result, stage="fem", scene_text=scene.text, inputs_hash=h,
                       extra_attrs={f"time_{k}_s": v for k, v in timings.items()})
    print(f"  {result.K.shape[0]} free dof; " + ", ".join(f"{k} {v:.1f} s" for k, v in timings.items()))
    print("  full-model frequencies, Hz: " + " ".join(f"{f:.2f}" for f in result.frequencies_hz[:6]))
    if scene.render.n_modes > 0:
        _render(scene, out)


def _read_fem(out: Path):
    from fem.analysis import FemResult

    return art.read_artifact(out / "fem.h5", FemResult)


def _render(scene, out: Path, n_modes=None):
    from pipelines.render import render_artifacts

    n = scene.render.n_modes if n_modes is None else n_modes
    paths = render_artifacts(out / "mesh.h5", out / "fem.h5", out / "figures", n_modes=n, scale=scene.render.scale,
                             window=tuple(scene.render.window), title_prefix=f"{scene.name}: ")
    print(f"  rendered {len(paths)} mode shapes -> {out / 'figures'}")
    return paths


# --- rom ---------------------------------------------------------------------------
def _run_rom(scene, out: Path, h: str):
    import numpy as np

    from rom.craig_bampton import build_craig_bampton

    rom = build_craig_bampton(_read_fem(out), _read_mesh(out), scene.rom)
    art.write_artifact(out / "rom.h5", rom, stage="rom", scene_text=scene.text, inputs_hash=h)
    k = min(6, len(rom.full_frequencies))
    err = (rom.frequencies[:k] - rom.full_frequencies[:k]) / rom.full_frequencies[:k]
    print(f"  {rom.n_dof} dof ({3 * rom.n_boundary} boundary + {rom.n_dof - 3 * rom.n_boundary} modal)")
    print("  ROM frequencies, Hz:  " + " ".join(f"{f:.2f}" for f in rom.frequencies[:k] / (2 * np.pi)))
    print("  error vs full model:  " + " ".join(f"{100 * e:+.3f}%" for e in err))


def read_rom(out: Path):
    """The ROM artifact of an output folder."""
    from rom.model import RomModel

    return art.read_artifact(out / "rom.h5", RomModel)


# --- hbm ---------------------------------------------------------------------------
def _provenance(scene, h: str, stage: str) -> dict:
    return {"stage": stage, "units": art.UNITS_SI, "scene": scene.text, "inputs_hash": h,
            "code_version": art.code_version()}


def _run_hbm(scene, out: Path, h: str):
    from pipelines.branch_store import BranchStore, load_branch, partial_path
    from hbm.harmonic.nfrc import compute_nfrc

    rom = read_rom(out)
    for method in scene.hbm.methods:
        final = out / f"nfrc_{method}.h5"
        part = partial_path(final)
        resume = None
        if part.is_file() and art.read_attrs(part).get("inputs_hash") == h:
            # an interrupted run of exactly these inputs: keep its points and go on from them
            resume = load_branch(part, allow_partial=True)
            store = BranchStore.reopen(part)
            print(f"  {method}: resuming from {store.n_points} points on disk")
        else:
            store = None
        t0 = time.perf_counter()

        def on_point(point, extras, _m=method):
            nonlocal store
            if store is None:
                store = BranchStore.create(final, len(point.x), attrs={**_provenance(scene, h, "hbm"),
                                                                       "method": _m})
            store.append(point, extras)

        try:
            result = compute_nfrc(rom, scene.casing, scene.contact, scene.hbm, method=method,
                                  on_point=on_point, resume=resume)
        finally:
            if store is not None:
                store.close()
        if store is None:  # not even a start point: still record why, in a complete file
            store = BranchStore.create(final, result.unknowns.shape[-1] if result.unknowns.ndim == 2 else 0,
                                       attrs={**_provenance(scene, h, "hbm"), "method": method})
            store.close()
        BranchStore.reopen(part).finalize(result.status)
        ok = int(result.converged.sum())
        print(f"  {method}: {len(result.omega)} points ({ok} converged), {time.perf_counter() - t0:.1f} s, "
              f"status: {result.status}")
    _plot_nfrc(scene, out)


def _plot_nfrc(scene, out: Path):
    from pipelines.branch_store import load_branch
    from pipelines.figures import plot_nfrc

    curves = {}
    for method in scene.hbm.methods:
        stored = load_branch(out / f"nfrc_{method}.h5")
        curves[f"{method.upper()}-HBM"] = (stored.branch.omega, stored.extras["le_amplitude"],
                                           stored.branch.converged)
    ti = None
    if (out / "ti.h5").is_file():
        import h5py

        with h5py.File(out / "ti.h5", "r") as h5:
            g = h5["sweep"]
            ti = (g["omega"][()], g["amplitude"][()], g["period_class"][()])
    if curves or ti is not None:
        path = plot_nfrc(curves, out / "figures" / "nfrc.png", ti_points=ti,
                         omega_range=(scene.hbm.omega_start, scene.hbm.omega_end))
        print(f"  figure: {path}")


# --- ti ----------------------------------------------------------------------------
@dataclass(frozen=True)
class TiArtifact:
    """What ti.h5 holds: the sweep and, when an NFRC exists, the validation of its
    highest-amplitude point by time marching from the HBM solution."""

    sweep: SweepResult
    validation: ValidationResult | None = None


def _run_ti(scene, out: Path, h: str):
    import numpy as np

    from hbm.ti.sweep import sweep
    from pipelines.figures import plot_ti_sweep

    rom = read_rom(out)
    result = sweep(rom, scene.casing, scene.contact, scene.ti)
    counts = np.bincount(result.period_class.astype(int), minlength=4)
    print(f"  {len(result.omega)} speeds; classes 2W/W/sub/none: {counts.tolist()}; "
          f"median {np.median(result.cpu_time):.1f} s per speed")
    validation = _validate(scene, out, rom) if scene.hbm.methods else None
    art.write_artifact(out / "ti.h5", TiArtifact(result, validation), stage="ti", scene_text=scene.text,
                       inputs_hash=h)
    plot_ti_sweep(result.omega, result.amplitude, result.period_class, out / "figures" / "ti_sweep.png")
    if scene.hbm.methods:
        _plot_nfrc(scene, out)


def _validate(scene, out: Path, rom):
    """March from the highest-amplitude converged point of the first NFRC and compare."""
    import numpy as np

    from pipelines.branch_store import load_branch
    from hbm.harmonic.residual import build_residual
    from hbm.ti.validation import validate_against_hbm
    from pipelines.figures import plot_time_signals

    method = scene.hbm.methods[0]
    path = out / f"nfrc_{method}.h5"
    if not path.is_file():
        return None
    stored = load_branch(path)
    b = stored.branch
    amp = np.where(b.converged, stored.extras["le_amplitude"], -np.inf)
    i = int(np.argmax(amp))
    res = build_residual(rom, scene.casing, scene.contact, scene.hbm, method=method)
    u, omega = b.x[i], float(b.omega[i])
    coeffs = res.expand_harmonics(u, omega)
    lam = res.signals(u, omega)["lam"]
    v = validate_against_hbm(rom, scene.casing, scene.contact, coeffs, omega, forces=lam, n_periods=100,
                             dt=scene.ti.dt)
    print(f"  validation at Omega = {omega:.1f} rad/s ({method.upper()}-HBM peak): displacement error "
          f"LE {100 * v.displacement_error[0]:.2f} %, TE {100 * v.displacement_error[1]:.2f} %; "
          f"force error LE {100 * v.force_error[0]:.1f} %, TE {100 * v.force_error[1]:.1f} %")
    t = v.tau / omega
    plot_time_signals(t, {f"{method.upper()}-HBM LE": 1e3 * v.hbm_displacement[:, 0],
                          "TI LE": 1e3 * v.ti_displacement[:, 0],
                          f"{method.upper()}-HBM TE": 1e3 * v.hbm_displacement[:, 1],
                          "TI TE": 1e3 * v.ti_displacement[:, 1]},
                      out / "figures" / "validation_displacement.png", "radial displacement (mm)")
    plot_time_signals(t, {f"{method.upper()}-HBM LE": v.hbm_force[:, 0], "TI LE": v.ti_force[:, 0],
                          f"{method.upper()}-HBM TE": v.hbm_force[:, 1], "TI TE": v.ti_force[:, 1]},
                      out / "figures" / "validation_force.png", "normal contact force (N)")
    return v


REGISTRY: dict[str, Stage] = {
    # the geometry file enters by content (inputs_hash), not by how its path is written
    "mesh": Stage("mesh", ("mesh",), (), lambda s: ("mesh.h5",), _run_mesh,
                  extra=lambda s: repr(dataclasses.replace(s.blade, geometry=""))),
    "fem": Stage("fem", ("material", "fem", "render"), ("mesh",), lambda s: ("fem.h5",), _run_fem,
                 extra=lambda s: f"eta={s.rom.n_fixed_modes}"),
    "rom": Stage("rom", ("rom",), ("fem",), lambda s: ("rom.h5",), _run_rom),
    "hbm": Stage("hbm", ("casing", "contact", "hbm"), ("rom",),
                 lambda s: tuple(f"nfrc_{m}.h5" for m in s.hbm.methods), _run_hbm),
    "ti": Stage("ti", ("casing", "contact", "ti", "hbm"), ("rom", "hbm"), lambda s: ("ti.h5",), _run_ti),
}


def _require_stage(name: str) -> Stage:
    try:
        return REGISTRY[name]
    except KeyError:
        raise NotImplementedError(f"stage '{name}' is not available in this version") from None


def run_scene(scene, out: Path, until: str = "rom", force: bool = False) -> None:
    """Run the scene's stages in order up to `until`, skipping those already up to date."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    for name in STAGES[: STAGES.index(until) + 1]:
        stage = _require_stage(name)
        h = inputs_hash(scene, out, stage)
        outputs = stage.outputs(scene)
        if not force and all(art.is_current(out / o, h) for o in outputs):
            print(f"[{name}] up to date ({', '.join(outputs)})")
            continue
        print(f"[{name}] running ...", flush=True)
        t0 = time.perf_counter()
        stage.run(scene, out, h)
        print(f"[{name}] done in {time.perf_counter() - t0:.1f} s -> {', '.join(outputs)}", flush=True)


def render_modes(scene, out: Path, n_modes=None):
    """Render the first mode shapes of `out/fem.h5` to PNG (off-screen)."""
    out = Path(out)
    return _render(scene, out, n_modes)
