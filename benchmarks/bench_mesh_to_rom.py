"""Mesh -> FEM -> Craig-Bampton ROM: wall time per step, peak memory, frequencies, ROM error.

    .venv/bin/python benchmarks/bench_mesh_to_rom.py [--scene coarse|default] [--box SIZE] [--rhs] [--solver S]
                                                     [--node-order rcm|meshed]
    mpirun -n 2 .venv/bin/python benchmarks/bench_mesh_to_rom.py ...      (the FEM stage on 2 ranks)

--scene: the rotor 67 blade meshed by mesh.blade.mesh_blade with scenes/rotor67_coarse.toml
(coarse) or scenes/rotor67.toml (default, about 200 000 nodes).
--box SIZE: instead of the blade, a 0.2 x 0.1 x 0.01 m box of tet10 with edge SIZE m
(0.0019 gives ~220 000 nodes, ~655 000 dof), clamped at x = 0.
--solver: [fem] solver (auto: CHOLMOD in one process, MUMPS under mpirun; or cholmod, mumps).
--node-order: the mesh's node order (mesh.ordering; "meshed": gmsh's, as before the
product renumbered its meshes), for the blade only.
--rhs: after the run, factorise K again and time one block solve of 14 right-hand sides
(MatMatSolve, what the FEM stage uses) against 14 single solves (a KSP loop).
Under mpirun (more than one rank) rank 0 meshes, all ranks assemble, factorise and solve
(fem.analysis, as `mpirun -n N bladerub run`), rank 0 gathers, writes fem.h5 and builds
the ROM, exactly the stages' split; one rank (no mpirun, or mpirun -n 1) is the serial path.
Peak memory is ru_maxrss of each rank (this process; children, such as none here, would
count as their own max). CPU is user + system time of each rank.
"""
from __future__ import annotations

import argparse
import resource
import sys
import tempfile
import time
from pathlib import Path

import hbm  # noqa: F401  (before numpy: OpenBLAS's kernels for the host, hbm.openblas)
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def peak_mb() -> float:
    s = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    c = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    return max(s, c) / 1024.0


def cpu_s() -> float:
    """User + system CPU time of this process, s: what the steps cost on a machine shared
    with other jobs, where wall time depends on the neighbours."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def cores_and_threads() -> tuple[int, int]:
    """(cores this process may run on, BLAS threads): mpirun binds each rank to a core by
    default (Open MPI, 2 ranks or fewer), and OpenBLAS sizes its pool from that."""
    import os

    from threadpoolctl import threadpool_info

    blas = [p["num_threads"] for p in threadpool_info() if p.get("user_api") == "blas"]
    return len(os.sched_getaffinity(0)), max(blas, default=0)


def make_mesh(args):
    if args.box:
        sys.path.insert(0, str(ROOT / "tests" / "fem"))
        from box_mesh import box_mesh

        # a box's tip nodes span no angle: "le-leads" has no meaning there, any sign does
        return box_mesh(0.2, 0.1, 0.01, args.box), f"box 0.2x0.1x0.01 m, h = {args.box} m", "+"
    from mesh.blade import mesh_blade
    from pipelines.scene import load_scene

    scene = load_scene(ROOT / "scenes" / {"coarse": "rotor67_coarse.toml", "default": "rotor67.toml"}[args.scene])
    mopt = scene.mesh
    return (mesh_blade(scene.blade, mopt, scene.resolve(scene.blade.geometry), node_order=args.node_order),
            f"rotor 67, scene {args.scene}, nodes in {args.node_order} order", scene.blade.rotation)


def compare_rhs(system, n_rhs: int = 14, solver: str = "auto") -> tuple[float, float, float]:
    """Seconds of (factorisation, one block solve of n_rhs columns, n_rhs single solves)."""
    from fem.cholesky import CholeskyFactor
    from fem.distributed import Local

    layout = getattr(system, "layout", None) or Local(system.n_free)
    B = layout.take(np.random.default_rng(1).standard_normal((system.n_free, n_rhs)))
    t = time.perf_counter()
    factor = CholeskyFactor(system.K, solver=solver)
    t_fact = time.perf_counter() - t
    try:
        t = time.perf_counter()
        X1 = factor.solve(B)
        t_block = time.perf_counter() - t
        t = time.perf_counter()
        X2 = factor.solve_columns(B)
        t_loop = time.perf_counter() - t
    finally:
        factor.destroy()
    assert np.allclose(X1, X2, rtol=1e-10, atol=1e-12 * np.abs(X1).max())
    return t_fact, t_block, t_loop


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scene", choices=("coarse", "default"), default="coarse")
    p.add_argument("--box", type=float, default=None)
    p.add_argument("--rhs", action="store_true", help="also time a block solve against a loop of single solves")
    p.add_argument("--solver", default="auto", help="[fem] solver: auto, cholmod or mumps")
    p.add_argument("--node-order", default="rcm", choices=("rcm", "meshed"), help="the blade mesh's node order")
    p.add_argument("--tmp", type=Path, default=None, help="folder for the timed fem.h5 write (default: a temp dir)")
    args = p.parse_args(argv)

    from fem.analysis import solve_system
    from fem.assembly import assemble_distributed, assemble_system
    from fem.material import Material
    from fem.options import FemOptions
    from pipelines import artifacts as art
    from pipelines.parallel import on_root, world
    from rom.craig_bampton import build_craig_bampton
    from rom.options import RomOptions

    from petsc4py import PETSc

    PETSc.Log.begin()  # event times: the factorisation's analysis vs numeric phase, the solves
    comm = world()
    rank, size = (comm.rank, comm.size) if comm is not None else (0, 1)
    say = print if rank == 0 else (lambda *a, **k: None)
    wall: dict[str, float] = {}

    t0 = time.perf_counter()
    # the other ranks wait idle (a blocking MPI wait would spin a core), as in the pipeline
    mesh, what, rotation = on_root(comm, lambda: make_mesh(args))
    wall["mesh (rank 0)"] = time.perf_counter() - t0
    say(f"{what}: {mesh.n_nodes} nodes, {len(mesh.cells)} tet10; {size} rank(s)", flush=True)

    t = time.perf_counter()
    if comm is None:
        system = assemble_system(mesh.nodes, mesh.cells, mesh.root_facets, Material())
    else:
        system = assemble_distributed(mesh.nodes, mesh.cells, mesh.root_facets, Material(), comm)
    wall["assembly"] = time.perf_counter() - t
    timings: dict = {}
    fem = solve_system(system, FemOptions(solver=args.solver), mesh.boundary_node_index, timings)
    events = {k: PETSc.Log.Event(e).getPerfInfo() for k, e in
              (("analysis", "MatCholFctrSym"), ("numeric", "MatCholFctrNum"), ("solve", "MatMatSolve"),
               ("matmult", "MatMatMultNum"))}
    for k in ("factorisation", "modes", "interface", "gather"):
        if k in timings:
            wall[{"modes": "full modes", "interface": "interface basis",
                  "gather": "gather to rank 0"}.get(k, k)] = timings[k]
    rhs = compare_rhs(system, solver=args.solver) if args.rhs else None
    if comm is not None:
        system.destroy()
    del system

    built = {}

    def finish():  # rank 0, the others wait idle
        if args.tmp is not None:
            args.tmp.mkdir(parents=True, exist_ok=True)  # mkdtemp needs the folder to exist
        with tempfile.TemporaryDirectory(dir=args.tmp) as tmp:
            t = time.perf_counter()
            art.write_artifact(Path(tmp) / "fem.h5", fem, stage="fem")
            wall["write fem.h5 (rank 0)"] = time.perf_counter() - t
        t = time.perf_counter()
        built["rom"] = build_craig_bampton(fem, mesh, RomOptions(), rotation=rotation)
        wall["ROM (rank 0)"] = time.perf_counter() - t

    on_root(comm, finish)
    rom = built.get("rom")
    total = time.perf_counter() - t0
    peaks = comm.gather(peak_mb(), root=0) if comm is not None else [peak_mb()]
    cores = comm.gather(cores_and_threads(), root=0) if comm is not None else [cores_and_threads()]
    cpus = comm.gather(cpu_s(), root=0) if comm is not None else [cpu_s()]
    if rank != 0:
        return

    n_free = fem.K.shape[0]
    print(f"{n_free} free dof, nnz(K) {fem.K.nnz}; factorised by {timings['solver']}; block solves: "
          f"modes {timings['modes_block_solves']}, interface {timings.get('interface_block_solves', 0)}")
    print(f"{'step':<24}{'wall s':>9}")
    for k, v in wall.items():
        print(f"{k:<24}{v:9.1f}")
    print(f"{'total mesh -> ROM':<24}{total:9.1f}")
    print("peak memory per rank, GB: " + " ".join(f"{m * 1024**2 / 1e9:.2f}" for m in peaks)
          + "; CPU per rank, s: " + " ".join(f"{c:.0f}" for c in cpus))
    e = events
    print(f"inside (rank 0, PETSc events): factorisation = analysis {e['analysis']['time']:.1f} s (ordering, "
          f"sequential) + numeric {e['numeric']['time']:.1f} s; {e['solve']['count']} block solves "
          f"{e['solve']['time']:.1f} s; distributed sparse products {e['matmult']['time']:.1f} s "
          f"({e['matmult']['count']})")
    print("cores allowed / BLAS threads per rank: " + " ".join(f"{c}/{t}" for c, t in cores))
    if rhs is not None:
        print(f"RHS comparison (second factorisation {rhs[0]:.1f} s): 14 right-hand sides in one block solve "
              f"{rhs[1]:.2f} s, as 14 single solves {rhs[2]:.2f} s")
    print(f"{'mode':>4} {'full Hz':>12} {'ROM Hz':>12} {'full rad/s':>12} {'ROM rad/s':>12} {'ROM err':>10}")
    for k in range(6):
        wf, wr = fem.frequencies[k], rom.frequencies[k]
        print(f"{k + 1:4d} {wf / 2 / np.pi:12.3f} {wr / 2 / np.pi:12.3f} {wf:12.2f} {wr:12.2f} {wr / wf - 1:10.2e}")
    print("fixed-interface frequencies (Hz):", np.round(rom.fixed_interface_frequencies / 2 / np.pi, 1))


if __name__ == "__main__":
    main()
