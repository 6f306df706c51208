"""Mesh -> FEM -> Craig-Bampton ROM: wall time per step, peak memory, frequencies, ROM error.

    .venv/bin/python benchmarks/bench_mesh_to_rom.py [--scene coarse|default] [--box SIZE]

--scene: the rotor 67 blade meshed by mesh.blade.mesh_blade with scenes/rotor67_coarse.toml
(coarse) or scenes/rotor67.toml (default, about 200 000 nodes).
--box SIZE: instead of the blade, a 0.2 x 0.1 x 0.01 m box of tet10 with edge SIZE m
(0.0019 gives ~220 000 nodes, ~655 000 dof), clamped at x = 0.
Peak memory is ru_maxrss of this process and its children (they are not added: max of the two).
"""
from __future__ import annotations

import argparse
import resource
import sys
import time
from pathlib import Path

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


def make_mesh(args):
    if args.box:
        sys.path.insert(0, str(ROOT / "tests" / "fem"))
        from box_mesh import box_mesh

        return box_mesh(0.2, 0.1, 0.01, args.box), f"box 0.2x0.1x0.01 m, h = {args.box} m"
    from mesh.blade import mesh_blade
    from pipelines.scene import load_scene

    scene = load_scene(ROOT / "scenes" / {"coarse": "rotor67_coarse.toml", "default": "rotor67.toml"}[args.scene])
    mopt = scene.mesh
    return mesh_blade(scene.blade, mopt, scene.resolve(scene.blade.geometry)), f"rotor 67, scene {args.scene}"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scene", choices=("coarse", "default"), default="coarse")
    p.add_argument("--box", type=float, default=None)
    args = p.parse_args(argv)

    from fem.analysis import solve_system
    from fem.assembly import assemble_system
    from fem.material import Material
    from fem.options import FemOptions
    from rom.craig_bampton import build_craig_bampton
    from rom.options import RomOptions

    t0 = time.perf_counter()
    mesh, what = make_mesh(args)
    c_mesh = cpu_s()
    t_mesh = time.perf_counter() - t0
    print(f"{what}: {mesh.n_nodes} nodes, {len(mesh.cells)} tet10, mesh {t_mesh:.1f} s (CPU {c_mesh:.1f} s), peak {peak_mb():.0f} MB",
          flush=True)
    t, c = time.perf_counter(), cpu_s()
    system = assemble_system(mesh.nodes, mesh.cells, mesh.root_facets, Material())
    t_asm = time.perf_counter() - t
    print(f"assembly: {system.n_free} free dof, nnz(K) {system.K.nnz}, {t_asm:.1f} s (CPU {cpu_s() - c:.1f} s), "
          f"peak {peak_mb():.0f} MB",
          flush=True)
    c = cpu_s()
    timings = {}
    fem = solve_system(system, FemOptions(), mesh.boundary_node_index, timings)
    print(f"factorisation {timings['factorisation']:.1f} s, full modes {timings['modes']:.1f} s "
          f"({timings['modes_block_solves']} block solves), constraint + fixed-interface modes "
          f"{timings['interface']:.1f} s ({timings.get('interface_block_solves', 0)} block solves); "
          f"CPU {cpu_s() - c:.1f} s; peak {peak_mb():.0f} MB", flush=True)
    t, c = time.perf_counter(), cpu_s()
    rom = build_craig_bampton(fem, mesh, RomOptions())
    t_rom = time.perf_counter() - t
    total = time.perf_counter() - t0
    print(f"ROM build {t_rom:.1f} s (CPU {cpu_s() - c:.1f} s); total mesh -> ROM {total:.1f} s "
          f"({total / 60:.2f} min), CPU {cpu_s():.1f} s; peak memory {peak_mb() / 1024:.2f} GB", flush=True)
    print(f"{'mode':>4} {'full Hz':>12} {'ROM Hz':>12} {'full rad/s':>12} {'ROM rad/s':>12} {'ROM err':>10}")
    for k in range(6):
        wf, wr = fem.frequencies[k], rom.frequencies[k]
        print(f"{k + 1:4d} {wf / 2 / np.pi:12.3f} {wr / 2 / np.pi:12.3f} {wf:12.2f} {wr:12.2f} {wr / wf - 1:10.2e}")
    print("fixed-interface frequencies (Hz):", np.round(rom.fixed_interface_frequencies / 2 / np.pi, 1))


if __name__ == "__main__":
    main()
