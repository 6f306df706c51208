"""Stage hbm: one NFRC per contact treatment (nfrc_dlft.h5, nfrc_rl.h5), each its own
output: a finished treatment is never recomputed because another one changed or failed.

Points are appended to NAME.partial.h5 as they are computed (pipelines.branch_store); an
interrupted run of the same inputs resumes from them.
"""
from __future__ import annotations

import time

from pipelines import artifacts as art
from pipelines.stages.base import Context, Estimate, Figure, Output, Stage
from pipelines.stages.rom import read_rom

#: Units of the per-point extras that compute_nfrc hands over (hbm.harmonic.nfrc.nfrc_extras).
EXTRA_UNITS = {"le_amplitude": "m", "le_max": "m", "harmonics": "m"}


#: The contact keys each treatment reads beyond the common ones (mu, and epsilon, which RL's
#: start strategy uses too: it starts from the DLFT solution when its own Newton fails).
_TREATMENT_KEYS = {"dlft": (), "rl": ("contact.kappa", "contact.gamma", "contact.lanczos")}


def nfrc_output(method: str) -> Output:
    return Output(f"nfrc_{method}.h5", key=method, depends=_TREATMENT_KEYS[method])


def _outputs(scene) -> tuple[Output, ...]:
    return tuple(nfrc_output(m) for m in scene.hbm.methods)


def _compute(ctx: Context, outputs) -> None:
    rom = read_rom(ctx.out)
    for output in outputs:
        _run_method(ctx, rom, output)


def _run_method(ctx: Context, rom, output: Output) -> None:
    from hbm.harmonic.nfrc import compute_nfrc
    from pipelines.branch_store import BranchStore, load_branch, partial_path

    scene, method = ctx.scene, output.key
    final = ctx.out / output.file
    part = partial_path(final)
    attrs = {**ctx.attrs(output, "hbm"), "method": method}
    resume, store = None, None
    if part.is_file() and art.read_attrs(part).get("inputs_hash") == ctx.hashes[output.file]:
        # an interrupted run of exactly these inputs: keep its points and go on from them
        try:
            resume = load_branch(part, allow_partial=True)
            store = BranchStore.reopen(part)
            ctx.log(f"  {method}: resuming from {store.n_points} points on disk")
        except (OSError, ValueError, KeyError) as exc:  # a run killed inside an HDF5 write
            resume, store = None, None
            ctx.progress.warn(f"{part.name} cannot be read ({art.first_line(exc)}): the {method} NFRC starts over")
    t0 = time.perf_counter()
    with ctx.progress.step(f"hbm {method}", None) as update:
        def on_point(point, extras):
            nonlocal store
            if store is None:
                store = BranchStore.create(final, len(point.x), attrs=attrs, units=EXTRA_UNITS)
            store.append(point, extras)
            update(f"\u03a9 = {point.omega:.1f} rad/s, {point.index + 1} points, ds = {point.step:.3g}")

        try:
            result = compute_nfrc(rom, scene.casing, scene.contact, scene.hbm, method=method, on_point=on_point,
                                  resume=resume)
        finally:
            if store is not None:
                store.close()
    if store is None:  # not even a start point: still record why, in a complete file
        BranchStore.create(final, result.unknowns.shape[-1] if result.unknowns.ndim == 2 else 0,
                           attrs=attrs, units=EXTRA_UNITS).close()
    tables = {}
    if scene.hbm.stability:  # the bifurcations located along the branch
        from hbm.stability.bifurcation import bifurcation_arrays

        tables["bifurcations"] = bifurcation_arrays(result.bifurcations)
    BranchStore.reopen(part).finalize(result.status, tables=tables)
    ok = int(result.converged.sum())
    ctx.log(f"  {method}: {len(result.omega)} points ({ok} converged), {time.perf_counter() - t0:.1f} s, "
            f"status: {result.status}")


def _nfrc_inputs(scene) -> tuple[str, ...]:
    return tuple(o.file for o in _outputs(scene)) + ("ti.h5",)


def draw_nfrc(ctx: Context) -> None:
    """The NFRC figure (the paper's Fig. 6): every treatment's curve, and the time-integration
    sweep's points by periodicity class when ti.h5 exists."""
    import h5py

    from pipelines.branch_store import load_branch
    from pipelines.figures import plot_nfrc

    scene, out = ctx.scene, ctx.out
    curves = {}
    for o in _outputs(scene):
        if (out / o.file).is_file():
            stored = load_branch(out / o.file)
            curves[f"{o.key.upper()}-HBM"] = (stored.branch.omega, stored.extras["le_amplitude"],
                                             stored.branch.converged)
    ti = None
    if (out / "ti.h5").is_file():
        with h5py.File(out / "ti.h5", "r") as h5:
            g = h5["sweep"]
            ti = (g["omega"][()], g["amplitude"][()], g["period_class"][()])
    if curves or ti is not None:
        plot_nfrc(curves, out / "figures" / "nfrc.png", ti_points=ti,
                  omega_range=(scene.hbm.omega_min, scene.hbm.omega_max))


NFRC_FIGURE = Figure("nfrc", files=lambda scene: ("nfrc.png",), depends=("hbm.omega_min", "hbm.omega_max"),
                     inputs=_nfrc_inputs, draw=draw_nfrc)

def _estimate(scene, out, outputs) -> Estimate:
    """Unknowns n_u = (2 N_h + 1) 3 n_b per point. Memory: the worst case is the dense
    fallback at a singular start (hbm.continuation.arclength.tangent: the SVD of the dense
    [J, dR/domega] needs ~10 n_u^2 doubles, measured at n_u = 2000 and 4000); the structured
    solves need far less. Time per point ~ a n_c + b n_c^3 (n_c = 2 N_h + 1: the AFT, then the
    m x m preconditioner LU, m <= n_c n_b), fitted to 30 points from 2000 rad/s on the coarse
    ROM at N_h = 10 to 160 (0.06 to 0.9 s per point); a whole NFRC is ~600-1800 points
    (default scene: 1176 DLFT, 1830 RL), max_points at most."""
    h = scene.hbm
    n_c = 2 * h.n_harmonics + 1
    n_u = n_c * 3 * scene.mesh.n_boundary
    per_point = (1.13e-3 * n_c + 1.56e-8 * n_c ** 3) * scene.mesh.n_boundary / 9
    points = min(h.max_points, 1500)
    from pipelines.guard import count

    return Estimate(size=f"{len(outputs)} NFRC(s) of {count(n_u)} unknowns (N_h = {h.n_harmonics})",
                    memory=0.2e9 + 10 * n_u ** 2 * 8.0, seconds=len(outputs) * points * per_point,
                    disk=len(outputs) * h.max_points * (n_u + n_c * 3 * scene.mesh.n_boundary + 16) * 8.0,
                    advice=f"lower [hbm] n_harmonics (now {h.n_harmonics}; the reference is 40)")


# hbm~methods: adding or removing a treatment leaves the other's NFRC current
STAGE = Stage("hbm", depends=("casing", "contact.mu", "contact.epsilon", "hbm~methods"), upstream=("rom",),
              outputs=_outputs, compute=_compute, figures=(NFRC_FIGURE,), estimate=_estimate)
