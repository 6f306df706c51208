"""Stage hbm: one NFRC per contact treatment (nfrc_dlft.h5, nfrc_rl.h5), each its own
output: a finished treatment is never recomputed because another one changed or failed.

Points are appended to NAME.partial.h5 as they are computed (pipelines.branch_store); an
interrupted run of the same inputs resumes from them. The treatments are independent
continuations of one core each, so they run at once, one process per core (one after the
other on one core, or under an MPI launcher, where the stage runs on rank 0).
"""
from __future__ import annotations

import time

import numpy as np

from pipelines import artifacts as art
from pipelines.stages import treatments
from pipelines.stages.base import Context, Estimate, Figure, Output, Stage
from pipelines.stages.rom import read_rom, warn_friction_lock
from pipelines.stages.treatments import Reporter, run_treatments

#: Units of the per-point extras that compute_nfrc hands over (hbm.harmonic.nfrc.nfrc_extras).
EXTRA_UNITS = {"le_amplitude": "m", "le_max": "m", "harmonics": "m", "modal_contribution": "1",
               "harmonic_contribution": "m", "stability_cpu_time": "s"}


#: The contact keys each treatment reads beyond the common ones (mu, and epsilon, which RL's
#: start strategy uses too: it starts from the DLFT solution when its own Newton fails).
_TREATMENT_KEYS = {"dlft": (), "rl": ("contact.kappa", "contact.gamma", "contact.lanczos")}


def nfrc_output(method: str) -> Output:
    return Output(f"nfrc_{method}.h5", key=method, depends=_TREATMENT_KEYS[method])


def _outputs(scene) -> tuple[Output, ...]:
    return tuple(nfrc_output(m) for m in scene.hbm.methods)


def _compute(ctx: Context, outputs, workers: int | None = None) -> None:
    """workers: processes, one treatment each (default: one per core, at most one per
    treatment; 1 runs them one after the other in this process)."""
    warn_friction_lock(ctx, read_rom(ctx.out))
    run_treatments(ctx, {o.key: o for o in outputs}, _nfrc, "hbm", "NFRC", workers)


def _nfrc(ctx: Context, output: Output, say: Reporter) -> None:
    """One treatment's NFRC (run_treatments' work)."""
    _run_method(ctx, read_rom(ctx.out), output, say)


def _run_method(ctx: Context, rom, output: Output, say: Reporter) -> None:
    from hbm.harmonic.nfrc import compute_nfrc
    from hbm.stability.bifurcation import bifurcation_arrays, bifurcations_from_arrays
    from pipelines.branch_store import BranchStore, load_branch, partial_path, read_tables

    scene, method = ctx.scene, output.key
    final = ctx.out / output.file
    part = partial_path(final)
    attrs = {**ctx.attrs(output, "hbm"), "method": method}
    resume, store, resumed_bifurcations = None, None, ()
    unreadable = art.read_failure(part) if part.is_file() else ""
    if unreadable:
        say.warn(f"{part.name} cannot be read ({unreadable}): the {method} NFRC starts over")
    elif part.is_file() and art.read_attrs(part).get("inputs_hash") == ctx.hashes[output.file]:
        # an interrupted run of exactly these inputs: keep its points and go on from them
        try:
            resume = load_branch(part, allow_partial=True)
            if not np.asarray(resume.branch.converged, dtype=bool)[:1].any():
                # interrupted before its start point was on disk: nothing to go on from (the
                # file is replaced by the first point)
                resume = None
                say.log(f"  {method}: {part.name} holds no start point: the NFRC starts over")
            else:
                store = BranchStore.reopen(part, units=EXTRA_UNITS)
                table = read_tables(part).get("bifurcations")
                resumed_bifurcations = bifurcations_from_arrays(table) if table else ()
                say.log(f"  {method}: resuming from {store.n_points} points on disk"
                        + (f" and {len(resumed_bifurcations)} bifurcations" if resumed_bifurcations else ""))
        except (OSError, ValueError, KeyError) as exc:  # a run killed inside an HDF5 write
            resume, store = None, None
            say.warn(f"{part.name} cannot be read ({art.first_line(exc)}): the {method} NFRC starts over")
    content, mode_frequencies = _content_of(rom, scene, method)
    t0 = time.perf_counter()

    def on_point(point, extras):
        nonlocal store
        if store is None:
            store = BranchStore.create(final, len(point.x), attrs=attrs, units=EXTRA_UNITS)
        store.append(point, {**extras, **content(point)})
        say.update(f"\u03a9 = {point.omega:.1f} rad/s, {point.index + 1} points, ds = {point.step:.3g}")

    def on_bifurcations(bifurcations):  # kept with the points, for a resume
        store.write_tables({"bifurcations": bifurcation_arrays(bifurcations)})

    try:
        result = compute_nfrc(rom, scene.casing, scene.contact, scene.hbm, method=method, on_point=on_point,
                              resume=resume, resume_bifurcations=resumed_bifurcations,
                              on_bifurcations=on_bifurcations)
    finally:
        if store is not None:
            store.close()
    if store is None:  # not even a start point: still record why, in a complete file
        BranchStore.create(final, result.unknowns.shape[-1] if result.unknowns.ndim == 2 else 0,
                           attrs=attrs, units=EXTRA_UNITS).close()
    tables = {"modes": {"frequencies": (mode_frequencies, "rad/s")}}
    if scene.hbm.stability:  # the bifurcations located along the branch
        tables["bifurcations"] = bifurcation_arrays(result.bifurcations)
    ok = int(result.converged.sum())
    # no point at all: what each start strategy gave at either end (the status holds only the
    # continuation's last Newton), in the file's detail and the log
    detail = f"no start point: {result.start}" if not ok else turned_back(result, scene.hbm)
    BranchStore.reopen(part).finalize(result.status, detail=detail, tables=tables)
    say.log(f"  {method}: {len(result.omega)} points ({ok} converged), {time.perf_counter() - t0:.1f} s, "
            f"status: {result.status}")
    if detail:
        say.warn(f"the {method} NFRC {'has ' if not ok else ''}{detail}")


def turned_back(result, hbm) -> str:
    """"" unless the NFRC ended at the end of the range it started from (e.g. past the
    friction lock, where the branch from 2000 rad/s turns back after a few rad/s): then which
    stretch of [omega_min, omega_max] holds none of its points, for the file's detail and the
    log. result: hbm.harmonic.nfrc.NfrcResult; hbm: the scene's HbmOptions."""
    from hbm.continuation.branch import STATUS_OMEGA_MAX, STATUS_OMEGA_MIN

    w = result.omega[np.asarray(result.converged, dtype=bool)]
    if result.status not in (STATUS_OMEGA_MAX, STATUS_OMEGA_MIN) or not len(w):
        return ""
    end = hbm.omega_max if result.status == STATUS_OMEGA_MAX else hbm.omega_min
    if not np.isclose(w[0], end, rtol=0, atol=1e-9 * end):
        return ""
    low, high = (hbm.omega_min, w.min()) if end == hbm.omega_max else (w.max(), hbm.omega_max)
    return (f"turned back at {w.min() if end == hbm.omega_max else w.max():.1f} rad/s and ended where it started "
            f"({end:g} rad/s): {low:.1f}-{high:.1f} rad/s holds none of its points (the isola search, "
            "--until isolas, looks there for other branches)")


def _content_of(rom, scene, method: str):
    """(content, frequencies): content(point) gives the point's modal and harmonic
    contributions (hbm.harmonic.content, eqs. 32-34), the extras modal_contribution (n,) of
    the ROM's n modes and harmonic_contribution (N_h + 1,), m; frequencies: those modes'
    frequencies (n,), rad/s (the table modes/frequencies)."""
    from hbm.harmonic.content import branch_content, rom_modes
    from hbm.harmonic.residual import build_residual

    res = build_residual(rom, scene.casing, scene.contact, scene.hbm, method=method)
    modes = rom_modes(rom.K, rom.M)

    def content(point) -> dict:
        c = branch_content(res, rom, np.asarray(point.x)[None], np.array([point.omega]), modes)
        return {k: c[k][0] for k in ("modal_contribution", "harmonic_contribution")}

    return content, modes[0]


def _nfrc_inputs(scene) -> tuple[str, ...]:
    return tuple(o.file for o in _outputs(scene)) + ("ti.h5",)


def draw_nfrc(ctx: Context) -> None:
    """The NFRC figure (the paper's Fig. 6): every treatment's curve, and the time-integration
    sweep's points by periodicity class when ti.h5 exists (ringed where pipelines.stages.ti's
    fallback WARNING names the speed)."""
    from pipelines.branch_store import load_branch
    from pipelines.figures import plot_nfrc
    from pipelines.stages.ti import FLAGGED_LABEL, sweep_points

    scene, out = ctx.scene, ctx.out
    curves = {}
    for o in _outputs(scene):
        if (out / o.file).is_file():
            stored = load_branch(out / o.file)
            curves[f"{o.key.upper()}-HBM"] = (stored.branch.omega, stored.extras["le_amplitude"],
                                             stored.branch.converged)
    ti = sweep_points(out)
    if curves or ti is not None:
        plot_nfrc(curves, out / "figures" / "nfrc.png", ti_points=ti,
                  omega_range=(scene.hbm.omega_min, scene.hbm.omega_max), n_lobes=scene.casing.n_lobes,
                  max_order=scene.ti.classified_order(scene.casing.n_lobes), flagged_label=FLAGGED_LABEL)


# hbm.methods: the curves' order gives their colours (the set of files alone does not change
# when the treatments are listed in another order)
NFRC_FIGURE = Figure("nfrc", files=lambda scene: ("nfrc.png",),
                     depends=("hbm.methods", "hbm.omega_min", "hbm.omega_max", "casing.n_lobes", "ti.max_order", "ti.n_keep"),
                     inputs=_nfrc_inputs, draw=draw_nfrc)


def _instants_stem(scene) -> str:
    return f"hbm_{scene.hbm.methods[0]}"


def _instants_files(scene) -> tuple[str, ...]:
    n = scene.render.hbm_instants
    if not scene.hbm.methods or n == 0:
        return ()
    stem = _instants_stem(scene)
    return (f"{stem}.pvd",) + tuple(f"{stem}/{stem}_{i:03d}.vtu" for i in range(n))


def chosen_point(stored, omega: float | None) -> int:
    """Index of the NFRC point written: the converged point nearest to omega, or the one of
    largest LE amplitude when omega is None. Raises ValueError without a converged point
    (its reason: the branch's status, e.g. a start point that did not converge)."""
    import numpy as np

    b = stored.branch
    ok = np.asarray(b.converged, bool)
    if not ok.any():
        status = getattr(b, "status", "")
        raise ValueError("the NFRC has no converged point to write" + (f" (its status: {status})" if status else ""))
    if omega is None:
        return int(np.argmax(np.where(ok, stored.extras["le_amplitude"], -np.inf)))
    return int(np.argmin(np.where(ok, np.abs(b.omega - omega), np.inf)))


def full_field_instants(rom, res, u, omega: float, n_instants: int):
    """Full-field displacement at n_instants evenly spaced over one period of an HBM solution.

    rom: RomModel with its recovery matrix (3 n_nodes, n). res: the HBM residual of that
    solution (its harmonics and linear-dof recovery). u: the point's unknowns; omega, rad/s.
    The period is that of the basis, 2 pi nu / Omega (nu = [hbm] subharmonic: nu revolutions).
    Returns (t (N,), s; displacement (N, n_nodes, 3), m).
    """
    import numpy as np

    from hbm.harmonic.fourier import FourierBasis

    nh = res.basis.n_harmonics
    per = -(-(2 * nh + 2) // n_instants)  # a basis fine enough for N_h, sampled every `per`
    basis = FourierBasis(nh, per * n_instants)
    x = basis.to_time(res.expand_harmonics(u, omega))[::per]  # (N, n) ROM dof, m
    field = np.asarray(rom.recovery, dtype=np.float64) @ x.T  # (3 n_nodes, N)
    return basis.tau[::per] / res.fundamental(omega), field.T.reshape(n_instants, -1, 3)


def write_hbm_vtu(ctx: Context) -> None:
    """figures/hbm_METHOD.pvd and hbm_METHOD/*.vtu: the blade's displacement over one period
    of one NFRC point (render.hbm_omega, or the largest amplitude), recovered from the ROM."""
    import h5py

    from hbm.harmonic.residual import build_residual
    from pipelines.branch_store import load_branch
    from pipelines.stages.mesh import MESH
    from pipelines.vtu import write_time_series

    scene, out = ctx.scene, ctx.out
    method = scene.hbm.methods[0]
    if not (out / nfrc_output(method).file).is_file():
        return  # no NFRC yet (its stage failed or was not run): drawn once it exists
    stored = load_branch(out / nfrc_output(method).file)
    try:
        i = chosen_point(stored, scene.render.hbm_omega)
    except ValueError as exc:  # the run's way out: a scene whose NFRC never starts
        raise ValueError(f"{nfrc_output(method).file}: {exc}; or write no NFRC point for ParaView in runs: "
                         "[render] hbm_instants = 0") from None
    u, omega = stored.branch.x[i], float(stored.branch.omega[i])
    rom = read_rom(out, with_recovery=True)
    if rom.recovery is None:
        raise art.ArtifactError(f"{out / 'rom.h5'} has no recovery matrix: cannot write full-field displacements")
    res = build_residual(rom, scene.casing, scene.contact, scene.hbm, method=method)
    t, disp = full_field_instants(rom, res, u, omega, scene.render.hbm_instants)
    with h5py.File(out / MESH.file, "r") as h5:
        nodes, cells = h5["nodes"][()], h5["cells"][()]
    amp = float(stored.extras["le_amplitude"][i])
    note = (f"{scene.name}: {method.upper()}-HBM NFRC point {i}, Omega = {omega:.6g} rad/s, LE amplitude "
            f"{amp:.6g} m; displacement in m over one period, recovered from the ROM")
    path = write_time_series(out / "figures", _instants_stem(scene), nodes, cells, t, disp, note)
    ctx.log(f"  {method.upper()}-HBM point {i} (Omega = {omega:.1f} rad/s, LE amplitude {1e3 * amp:.3f} mm): "
            f"{len(t)} instants -> {path}")


# name: the PVD's comment names the scene (as the mode pictures' titles do)
HBM_VTU = Figure("hbm_vtu", files=_instants_files,
                 depends=("render.hbm_instants", "render.hbm_omega", "hbm.methods", "name"),
                 inputs=lambda scene: tuple(nfrc_output(m).file for m in scene.hbm.methods[:1]) + ("mesh.h5", "rom.h5"),
                 draw=write_hbm_vtu)


def _estimate(scene, out, outputs) -> Estimate:
    """Unknowns n_u = (2 N_h + 1) 3 n_b per point. Memory: the worst case is the dense
    fallback at a singular start (hbm.continuation.arclength.tangent: the SVD of the dense
    [J, dR/domega] needs ~10 n_u^2 doubles, measured at n_u = 2000 and 4000); the structured
    solves need far less. Time per point ~ a n_c + b n_c^3 (n_c = 2 N_h + 1: the AFT, then the
    m x m preconditioner LU, m <= n_c n_b), fitted to 30 points from 2000 rad/s on the coarse
    ROM at N_h = 10 to 160 (0.06 to 0.9 s per point); a whole NFRC is ~600-1800 points
    (default scene: 1176 DLFT, 1830 RL), max_points at most. The treatments run at once on
    as many cores, one each (_workers): the time is that of the rounds they take, the
    memory that of the treatments at once.

    The AFT's time signals (N_t samples of each of the 3 n_b boundary dof: displacements,
    velocities, forces, the Jacobian's weights) add AFT_BYTES per sample and dof, and
    AFT_SECONDS per sample and dof for each residual and Jacobian of a point (a few Newton
    iterations: taken as 3); the time fitted above includes the AFT at the n_time it was
    fitted with, so a point costs the larger of the two. With [hbm] stability the time is
    STABILITY_FACTOR times that."""
    h = scene.hbm
    n_c = 2 * h.n_harmonics + 1
    n_r = 3 * scene.n_contact_nodes
    n_u = n_c * n_r
    aft = AFT_BYTES * h.n_time * n_r
    per_point = point_seconds(scene)
    points = min(h.max_points, 1500)
    at_once = treatments.treatment_workers(len(outputs))
    from pipelines.guard import count

    dense = 10 * n_u ** 2 * 8.0
    size = f"{len(outputs)} NFRC(s) of {count(n_u)} unknowns (N_h = {h.n_harmonics})"
    advice = f"lower [hbm] n_harmonics (now {h.n_harmonics}; the reference is 40)"
    if aft > dense:  # the AFT's signals, not the unknowns, drive the memory
        size = f"{len(outputs)} NFRC(s) of {count(n_u)} unknowns (N_h = {h.n_harmonics}, N_t = {count(h.n_time)})"
        advice = f"lower [hbm] n_time (now {h.n_time}; the reference is 1024)"
    return Estimate(size=size, memory=(0.2e9 + dense + aft) * at_once,
                    seconds=(-(-len(outputs) // at_once) * points * per_point
                             * (STABILITY_FACTOR if h.stability else 1.0)),
                    disk=len(outputs) * h.max_points * (n_u + n_c * 3 * scene.n_contact_nodes + 16) * 8.0,
                    advice=advice)


def point_seconds(scene) -> float:
    """The estimated CPU time of one continuation point of the scene's HBM, s (_estimate)."""
    h = scene.hbm
    n_c = 2 * h.n_harmonics + 1
    return max((1.13e-3 * n_c + 1.56e-8 * n_c ** 3) * scene.n_contact_nodes / 9,
               3 * AFT_SECONDS * h.n_time * 3 * scene.n_contact_nodes)


#: How many times longer an NFRC takes with [hbm] stability: RL, the slower treatment, 1.8 to
#: 2.4 times on the coarse ROM and 2.3 on the default one (README, *Stability and
#: bifurcations: what they cost*), 2.75 in the sum of its points' times on the default scene
#: on a Zen 3 host; DLFT 2.5 to 3.0 times, from a shorter time.
STABILITY_FACTOR = 2.5

#: Bytes of the AFT's time signals per sample (n_time) and boundary dof (3 n_b), rounded up
#: from 86 B: one residual with its Jacobian and a Jacobian product on the coarse rotor 67
#: ROM with every contact node in contact, N_h = 5, n_time = 2^14 to 2^18 (tracemalloc, DLFT
#: and RL alike; the process's peak RSS rose by 77-79 B at 2^21).
AFT_BYTES = 96.0
#: Seconds per sample and boundary dof of one residual with its Jacobian and a Jacobian
#: product, same measurement: 1.8e-7 (RL) to 6.1e-7 (DLFT) at n_time = 2^18, one core.
AFT_SECONDS = 4e-7


# hbm~methods: adding or removing a treatment leaves the other's NFRC current
STAGE = Stage("hbm", depends=("casing", "contact.mu", "contact.epsilon", "hbm~methods"), upstream=("rom",),
              outputs=_outputs, compute=_compute, figures=(NFRC_FIGURE, HBM_VTU), estimate=_estimate,
              busy_cores=lambda scene, outputs: treatments.treatment_workers(len(outputs)))
