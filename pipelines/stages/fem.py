"""Stage fem: dolfinx P2 elasticity, K and M, full-model modes and the Craig-Bampton
ingredients from one factorisation of K (fem.h5); the mode-shape pictures."""
from __future__ import annotations

import dataclasses

from pipelines import artifacts as art
from pipelines.stages.base import Context, Estimate, Figure, Output, Stage
from pipelines.stages.mesh import MESH, coarser_mesh, node_count, nodes_text, read_mesh

FEM = Output("fem.h5")


def read_fem(out):
    """The FemResult of an output folder."""
    from fem.analysis import FemResult

    return art.read_artifact(out / FEM.file, FemResult)


def _options(scene):
    """The FEM stage also computes the ROM's fixed-interface modes from its factorisation of K."""
    return dataclasses.replace(scene.fem, n_fixed_interface_modes=scene.fixed_interface_modes)


def _compute(ctx: Context, outputs) -> None:
    """Distributed under `mpirun -n N`: every rank reads mesh.h5, the ranks assemble and
    factorise together (fem.analysis), rank 0 gets the result in the serial numbering and
    writes fem.h5, the same file as one process writes."""
    from fem.analysis import analyse_blade
    from fem.options import FemOptions
    from pipelines.errors import deferred_ctrl_c
    from pipelines.parallel import on_root, world

    with deferred_ctrl_c():  # dolfinx's initialisation (MPI, PETSc) is not to be cut halfway
        import dolfinx.fem.petsc  # noqa: F401
    comm = world()
    mesh = read_mesh(ctx.out)
    timings: dict = {}
    with ctx.progress.step("fem", None) as update:
        ranks = f" on {comm.size} MPI ranks" if comm is not None else ""
        update(f"assembly, Cholesky factorisation, modes, interface basis{ranks}")
        # Ctrl-C held until the analysis returns, as for dolfinx's import: KeyboardInterrupt
        # raised inside it (form compilation, assembly, the factorisation's PETSc objects)
        # ended the run now and then on PETSc's SEGV handler, exit 59, before the run could
        # say what it kept (tests/pipelines/test_interrupt.py beside other tests). A longer
        # analysis is ended by the run's watcher after its grace (pipelines.cli), without
        # unwinding through it.
        with deferred_ctrl_c():
            result = analyse_blade(mesh, ctx.scene.material, _options(ctx.scene), timings=timings, comm=comm)

    def write():
        prov = ctx.provenance(FEM, "fem")
        # wall times as time_<step>_s; counts and sizes under their own names
        prov["extra_attrs"].update({f"time_{k}_s" if isinstance(v, float) else k: v for k, v in timings.items()})
        art.write_artifact(ctx.out / FEM.file, result, **prov)
        ctx.log(f"  {result.K.shape[0]} free dof{ranks}; "
                + ", ".join(f"{k} {v:.1f} s" if isinstance(v, float) else f"{k} {v}" for k, v in timings.items()))
        ctx.log("  full-model frequencies, Hz: " + " ".join(f"{f:.2f}" for f in result.frequencies_hz[:6]))
        asked, default = ctx.scene.fem.ordering, FemOptions().ordering
        if timings.get("solver") == "cholmod":
            if asked != default:
                ctx.log(f"  NOTE: [fem] ordering = \"{asked}\" is MUMPS's; CHOLMOD factorised K with its own choice "
                        f"of AMD or METIS ([fem] solver = \"mumps\" applies it)")
        elif asked != "auto" and timings.get("ordering", asked) != asked:
            ctx.log(f"  WARNING: [fem] ordering = \"{asked}\" is not in this MUMPS build; it used {timings['ordering']}")

    on_root(comm, write)


def fem_bytes(scene, nodes: float) -> float:
    """Size of fem.h5 for a mesh of `nodes` nodes, bytes: K and M in CSR (~66 entries per row
    for tet10, 8-byte values and 4-byte indices) and the full-model, constraint and
    fixed-interface modes (8 bytes per dof each). 144 MB for the coarse mesh (24 104 nodes)."""
    per_dof = 2 * 66 * 12 + 8 * (scene.fem.n_modes + 3 * scene.n_contact_nodes
                                 + scene.fixed_interface_modes)
    return 3 * nodes * per_dof


def _estimate(scene, out, outputs) -> Estimate | None:
    # Peak memory: in core, the Cholesky factor (factor_bytes, an upper bound from the split
    # decks) beside K and M's upper triangles, the eigen-solver's capped basis and its
    # blocks, ~8 kB per node, and 0.4 GB of libraries; out of core (MUMPS), ~23 kB per node.
    # Measured peaks (CHOLMOD in core, benchmarks/bench_mesh_to_rom.py and
    # bench_mesh_import.py): 0.66 GB for the coarse table mesh (24 104 nodes; estimate 0.79),
    # 5.26 GB for the default one (196 955; 6.7), 11.15 GB for the ~200k wedge deck split
    # into 319 011 tet10 nodes (12.7); out of core (MUMPS) 5.5 GB for that deck (7.5). Time
    # measured on 2 cores.
    from pipelines.guard import count

    n, exact = node_count(scene, out)
    advice = coarser_mesh(scene)
    if not scene.fem.out_of_core:
        advice += ", or set [fem] out_of_core = true" + (' and solver = "auto"' if scene.fem.solver == "cholmod" else "")
    memory = 0.2e9 + 23e3 * n if scene.fem.out_of_core else 0.4e9 + 8e3 * n + factor_bytes(n)
    return Estimate(size=f"{nodes_text(n, exact)}, {'' if exact else '~'}{count(3 * n)} dof",
                    memory=memory, seconds=0.033 * n ** 0.65, disk=fem_bytes(scene, n), advice=advice,
                    scratch=factor_bytes(n) if scene.fem.out_of_core else 0.0,
                    scratch_what="the out-of-core Cholesky factor",
                    scratch_advice="set [fem] out_of_core = false where the memory allows")


def factor_bytes(nodes: float) -> float:
    """Size of the files in which MUMPS keeps the Cholesky factor of K out of core, bytes,
    for a tet10 mesh of `nodes` nodes: 9.70e9 B at 319 011 nodes (the ~200k-node rotor 67
    wedge deck: 1.17e9 factor entries, 8.3 B each with MUMPS's index arrays) growing as
    nodes^1.5 (the factor entries of the decks split into 197 685 and 319 011 tet10 nodes
    grow with exponent 1.48). The table-built meshes, finer only at the LE and TE, have
    smaller factors per node: an upper bound for them."""
    return 9.70e9 * (nodes / 319011.0) ** 1.5


def mode_files(scene) -> tuple[str, ...]:
    return tuple(f"mode_{j + 1:02d}.png" for j in range(scene.render.n_modes))


def render_modes(ctx: Context, n_modes: int | None = None) -> list:
    """Render the first mode shapes of fem.h5 off-screen (in a child process, see
    pipelines.render.render_artifacts). Drawn for the scene (n_modes None), the pictures of
    modes beyond render.n_modes that an earlier, larger count left are removed once the new
    ones are written, so that figures/ holds what the manifest lists; a count asked for
    (`bladerub render --modes`) leaves the scene's other pictures alone."""
    from pipelines.render import render_artifacts
    from pipelines.vtu import remove_numbered

    scene = ctx.scene
    n = scene.render.n_modes if n_modes is None else n_modes
    if n == 0:
        return []
    with ctx.progress.step("render", None) as update:
        update(f"{n} mode shapes, off-screen")
        paths = render_artifacts(ctx.out / MESH.file, ctx.out / FEM.file, ctx.out / "figures", n_modes=n,
                                 scale=scene.render.scale, window=tuple(scene.render.window),
                                 title_prefix=f"{scene.name}: ")
    if n_modes is None:
        remove_numbered(ctx.out / "figures", "mode_", 2, ".png", n + 1)  # mode_files: 1-based
    ctx.log(f"  rendered {len(paths)} mode shapes -> {ctx.out / 'figures'}")
    return paths


def _draw_modes(ctx: Context) -> None:
    """The run's mode pictures (render_modes), with the run's way out where they cannot be drawn."""
    from pipelines.render import RenderError

    try:
        render_modes(ctx)
    except RenderError as exc:
        raise RenderError(f"{exc}; or draw no mode pictures in runs: [render] n_modes = 0") from None


MODES = Figure("modes", files=mode_files, depends=("render.n_modes", "render.scale", "render.window", "name"),
               inputs=lambda s: (MESH.file, FEM.file), draw=_draw_modes)


def write_modes_vtu(ctx: Context) -> None:
    """figures/modes.vtu: the first render.n_modes mode shapes for ParaView (pipelines.vtu)."""
    import h5py

    from pipelines.vtu import write_mode_shapes

    n = ctx.scene.render.n_modes
    with h5py.File(ctx.out / MESH.file, "r") as h5:
        nodes, cells = h5["nodes"][()], h5["cells"][()]
    with h5py.File(ctx.out / FEM.file, "r") as h5:  # only the shapes, not K, M and the interface basis
        modes, freqs = h5["modes"][:n], h5["frequencies_hz"][:n]
    path = write_mode_shapes(ctx.out / "figures" / "modes.vtu", nodes, cells, modes, freqs)
    ctx.log(f"  {len(modes)} mode shapes -> {path}")


MODES_VTU = Figure("modes_vtu", files=lambda s: ("modes.vtu",) if s.render.n_modes else (),
                   depends=("render.n_modes",), inputs=lambda s: (MESH.file, FEM.file), draw=write_modes_vtu)

# the count of fixed-interface modes computed, not the two keys it comes from: [rom]
# n_fixed_modes raised up to [fem] n_fixed_interface_modes leaves fem.h5 current; [fem] solver,
# ordering and out_of_core change fem.h5 at round-off only: hashed at their defaults
# (pipelines.runner.HOW_NOT_WHAT)
STAGE = Stage("fem", depends=("material~name", "fem~n_fixed_interface_modes", "fixed_interface_modes"), upstream=("mesh",),
              outputs=lambda scene: (FEM,), compute=_compute, figures=(MODES, MODES_VTU), estimate=_estimate,
              distributed=True)
