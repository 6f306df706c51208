"""Bring your own mesh: figures for the README.

    .venv/bin/python benchmarks/bench_mesh_import.py --boxes
    nice -n 10 .venv/bin/python benchmarks/bench_mesh_import.py --rotor67 [--size 0.0014 --layers 115] [--out-of-core] [--solver S]

--boxes: the clamped slender box of the tests (L = 0.3 m, b = 0.02 m, t = 0.01 m,
Ti-6Al-4V) as wedge15 and hex20 decks of three sizes: the product's first frequencies
(import -> split into tet10 -> dolfinx) against CalculiX (ccx, *FREQUENCY on the same
deck) and Euler-Bernoulli.

--rotor67: the rotor 67 blade as a user would bring it: a 15-node wedge deck (C3D15,
mm, root fixed in *BOUNDARY) of about 200 000 nodes, made here (not timed with the run)
as follows. gmsh meshes, in triangles of --size, a lens-shaped 2-D domain
(meridional fraction x mean meridional chord, +- the sections' mean half thickness) and
extrudes it in --layers layers of prisms over a unit span, second order incomplete
(wedge15). Every node of that parametric prism mesh, mid nodes included, is then mapped
onto the blade: at span fraction eta (in proportion to the sections' mean radius,
hub = surface 1, tip = surface 13) and meridional fraction s, the axial position, radius,
camber r*theta and half thickness are cubic splines across the 13 sections of
monotone-cubic (thickness) or cubic (the others) interpolants along each section, and the
lens coordinate scales to the local half thickness: the elements are curved, following
the table. Then `bladerub run SCENE --until rom` on a scene naming the deck is timed in a
child process; its peak memory is the largest stage peak of the run's summary. The
frequencies are printed beside those of the table-built default mesh (README).
--out-of-core: the scene sets [fem] out_of_core = true (MUMPS keeps the Cholesky factor
of K in files). --solver S: the scene sets [fem] solver = S (default: the scene's default,
auto: CHOLMOD in one process in core, else MUMPS). --ranks N: the run under `mpirun -n N`
(one BLAS thread per rank); the peak memory is then also given as the largest sum over the
ranks of their proportional set sizes (PSS, shared pages split between the processes that
map them), sampled every 0.5 s from /proc.
"""
from __future__ import annotations

import argparse
import os
import resource
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path

import hbm  # noqa: F401  (before numpy: OpenBLAS's kernels for the host, hbm.openblas)
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))
TABLE = ROOT.parent / "shared" / "data" / "rotor67" / "rotor67geometry.dat"
E, NU, RHO = 108e9, 0.34, 4400.0


# --- boxes -----------------------------------------------------------------------------
def boxes(sizes=((30, 2, 1), (60, 4, 2), (120, 8, 4))):
    import tempfile

    from decks import box, ccx_frequencies, root_nodes, write_deck
    from fem.assembly import assemble_system
    from fem.material import Material
    from fem.modes import compute_modes
    from mesh.imported import import_blade
    from mesh.options import BladeOptions, MeshOptions

    L, b, t = 0.3, 0.02, 0.01

    def eb(h, lam):
        return lam ** 2 / (2 * np.pi) * np.sqrt(E * h ** 2 / (12 * RHO * L ** 4))

    ref = np.array([eb(t, 1.875104068711961), eb(b, 1.875104068711961), eb(t, 4.694091132974175)])
    print(f"Euler-Bernoulli 1F / 1E / 2F: {ref[0]:.3f} / {ref[1]:.3f} / {ref[2]:.3f} Hz")
    print(f"{'deck':>12} {'divisions':>11} {'file nodes':>10} {'tet10 nodes':>11} {'mode':>4} {'ccx Hz':>10} "
          f"{'bladerub Hz':>11} {'vs ccx':>8} {'vs EB':>8}")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for kind in ("wedge15", "hexahedron20"):
            for n in sizes:
                bx = box(kind, L=L, b=b, t=t, n=n)
                deck = tmp / f"{kind}.inp"
                write_deck(deck, bx, units="mm", root=root_nodes(bx), material=(E, NU, RHO), n_modes=6, digits=12)
                fc = ccx_frequencies(deck, tmp / "ccx")
                m = import_blade(BladeOptions(mesh=deck.name, units="mm"), MeshOptions(n_boundary=3), deck)
                s = assemble_system(m.nodes, m.cells, m.root_facets, Material(E=E, nu=NU, rho=RHO))
                fp = compute_modes(s.K, s.M, 6).frequencies_hz
                for k in range(6):
                    vs_eb = f"{100 * (fp[k] / ref[k] - 1):+7.2f}%" if k < 3 else ""
                    print(f"{kind if k == 0 else '':>12} {'x'.join(map(str, n)) if k == 0 else '':>11} "
                          f"{len(bx.points) if k == 0 else '':>10} {m.n_nodes if k == 0 else '':>11} {k + 1:>4} "
                          f"{fc[k]:10.3f} {fp[k]:11.3f} {100 * (fp[k] / fc[k] - 1):+7.3f}% {vs_eb:>8}", flush=True)


# --- rotor 67 as a wedge15 deck ---------------------------------------------------------
def rotor67_wedge15(deck: Path, size: float, layers: int, hub: int = 1, tip: int = 13) -> dict:
    """Write rotor 67 (surfaces hub..tip) as a C3D15 deck in mm; returns counts."""
    import gmsh
    from scipy.interpolate import CubicSpline, PchipInterpolator

    from mesh.geometry import read_geometry

    geo = read_geometry(TABLE, "rotor67", "ft")
    sections = [geo.section(k) for k in range(hub, tip + 1)]
    along = []  # per section: s -> (z, r, camber r*theta, half thickness)
    for sec in sections:
        m = sec.meridional_arc()
        s = m / m[-1]
        along.append((CubicSpline(s, sec.z), CubicSpline(s, sec.r),
                      CubicSpline(s, sec.rtheta_upper - 0.5 * sec.thickness), PchipInterpolator(s, 0.5 * sec.thickness)))
    chord = float(np.mean([sec.meridional_arc()[-1] for sec in sections]))
    r_mean = np.array([sec.r.mean() for sec in sections])
    eta_k = (r_mean - r_mean[0]) / (r_mean[-1] - r_mean[0])

    def half_width(s):
        return np.mean([f[3](s) for f in along], axis=0)

    su = 0.5 * (1 - np.cos(np.linspace(0, np.pi, 81)))  # clustered at LE and TE
    gmsh.initialize(["-noenv"])
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("r67")
        g = gmsh.model.geo
        w = half_width(su)
        le, te = g.addPoint(0, 0, 0), g.addPoint(chord, 0, 0)
        upper = [le] + [g.addPoint(chord * s, y, 0) for s, y in zip(su[1:-1], w[1:-1])] + [te]
        lower = [te] + [g.addPoint(chord * s, -y, 0) for s, y in zip(su[-2:0:-1], w[-2:0:-1])] + [le]
        surf = g.addPlaneSurface([g.addCurveLoop([g.addSpline(upper), g.addSpline(lower)])])
        g.extrude([(2, surf)], 0, 0, 1.0, numElements=[layers], recombine=True)
        g.synchronize()
        # smaller triangles towards the LE and TE points, where the thickness vanishes and
        # the lens-to-blade map bends fastest (curved wedges there turn inside out otherwise)
        f = gmsh.model.mesh.field
        dist = f.add("Distance")
        f.setNumbers(dist, "PointsList", [le, te])
        thr = f.add("Threshold")
        f.setNumber(thr, "InField", dist)
        f.setNumber(thr, "SizeMin", size / 8)
        f.setNumber(thr, "SizeMax", size)
        f.setNumber(thr, "DistMin", 0.0)
        f.setNumber(thr, "DistMax", 6 * size)
        f.setAsBackgroundMesh(thr)
        gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
        gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
        gmsh.option.setNumber("Mesh.MeshSizeMax", size)
        gmsh.option.setNumber("Mesh.ElementOrder", 2)
        gmsh.option.setNumber("Mesh.SecondOrderIncomplete", 1)
        gmsh.model.mesh.generate(3)
        tags, coords, _ = gmsh.model.mesh.getNodes()
        _, enodes = gmsh.model.mesh.getElementsByType(18)
    finally:
        gmsh.finalize()
    p = np.asarray(coords).reshape(-1, 3)
    index = np.full(int(np.max(tags)) + 1, -1, dtype=np.int64)
    index[np.asarray(tags, dtype=np.int64)] = np.arange(len(tags))
    cells = index[np.asarray(enodes, dtype=np.int64)].reshape(-1, 15)
    cells = cells[:, [0, 1, 2, 3, 4, 5, 6, 9, 7, 12, 14, 13, 8, 10, 11]]  # gmsh -> Abaqus order
    used = np.unique(cells)
    renum = np.full(len(p), -1, dtype=np.int64)
    renum[used] = np.arange(len(used))
    p, cells = p[used], renum[cells]

    s = np.clip(p[:, 0] / chord, 0.0, 1.0)
    w = half_width(s)
    ratio = np.zeros_like(s)
    ok = w > 1e-12
    vals = np.empty((4, len(sections), len(p)))
    for k, f in enumerate(along):
        for q in range(4):
            vals[q, k] = f[q](s)
    ratio_k = np.where(ok, vals[3] / np.where(ok, w, 1.0), 0.0)  # local over mean half thickness
    out = np.empty_like(p)
    for level in np.unique(p[:, 2]):
        sel = p[:, 2] == level
        weights = CubicSpline(eta_k, np.eye(len(sections)))(level)
        z, r, c = (weights @ vals[q][:, sel] for q in range(3))
        ratio[sel] = weights @ ratio_k[:, sel]
        theta = (c - p[sel, 1] * ratio[sel]) / r  # -: (meridional, -theta, span) is right-handed
        out[sel] = np.column_stack([r * np.cos(theta), r * np.sin(theta), z])
    root = np.flatnonzero(p[:, 2] == 0.0)
    ids = np.arange(1, len(out) + 1)
    with open(deck, "w") as fh:
        fh.write("*HEADING\nrotor 67 (NASA table), 15-node wedges, mm; bladerub benchmark\n*NODE\n")
        np.savetxt(fh, np.column_stack([ids, 1e3 * out]), fmt=["%d", "%.10e", "%.10e", "%.10e"], delimiter=", ")
        fh.write("*ELEMENT, TYPE=C3D15, ELSET=BLADE\n")
        np.savetxt(fh, np.column_stack([np.arange(1, len(cells) + 1), ids[cells]]), fmt="%d", delimiter=", ")
        fh.write("*NSET, NSET=ROOT\n")
        r8 = ids[root]
        for i in range(0, len(r8), 8):
            fh.write(", ".join(map(str, r8[i:i + 8])) + "\n")
        fh.write("*BOUNDARY\nROOT, 1, 3\n")
    return {"nodes": len(out), "wedges": len(cells), "root_nodes": len(root)}


def rotor67(args):
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    deck = out / "rotor67_wedge15.inp"
    t0 = time.perf_counter()
    counts = rotor67_wedge15(deck, args.size, args.layers)
    print(f"deck {deck}: {counts['nodes']} nodes, {counts['wedges']} C3D15 wedges, {counts['root_nodes']} root nodes "
          f"(size {args.size} m, {args.layers} layers), written in {time.perf_counter() - t0:.1f} s "
          f"({deck.stat().st_size / 1e6:.1f} MB)", flush=True)
    scene = out / "scene.toml"
    scene.write_text('name = "rotor67_wedge15"\n[blade]\nmesh = "rotor67_wedge15.inp"\nunits = "mm"\naxis = "z"\n'
                     'root = "boundary"\n' + fem_section(args))
    if args.deck_only:
        return
    if args.steps:
        steps(deck, args.out_of_core, args.solver)
        return
    cmd = [sys.executable, "-m", "pipelines.cli", "run", str(scene), "--out", str(out / "run"), "--until",
           args.until, "--force"]
    env = {"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin", "HOME": str(Path.home())}
    if args.ranks > 1:
        cmd = [shutil.which("mpirun") or "mpirun", "-n", str(args.ranks)] + cmd
        env.update(OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", OMPI_ALLOW_RUN_AS_ROOT="1",
                   OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1", OMPI_MCA_rmaps_base_oversubscribe="1")
    t0 = time.perf_counter()
    # The run resets the kernel's high-water mark at each stage (pipelines.progress), so the
    # child's ru_maxrss is only the last stage's peak: take the largest peak of its summary
    # (rank 0's under mpirun; the sampler sums every process of the run).
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    sampler = TreeMemory(proc.pid)
    sampler.start()
    peaks = []
    for line in proc.stdout:
        print(line, end="", flush=True)
        cells = [c.strip() for c in line.strip().strip("│").split("│")]
        if len(cells) >= 3 and cells[2].endswith(" GB"):
            peaks.append(float(cells[2][:-3]))
    proc.wait()
    sampler.stop()
    wall = time.perf_counter() - t0
    if proc.returncode:
        raise SystemExit(proc.returncode)
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    print(f"bladerub run --until {args.until} on {args.ranks} rank(s): {wall:.1f} s wall ({wall / 60:.2f} min), CPU "
          f"{ru.ru_utime + ru.ru_stime:.1f} s (all threads; wall depends on the machine's other jobs), "
          f"peak memory {max(peaks, default=float('nan')):.2f} GB (largest stage peak of the run summary, rank 0), "
          f"{sampler.peak / 1e9:.2f} GB summed over the run's processes (PSS, sampled)")


def fem_section(args) -> str:
    """The scene's [fem] section for --out-of-core and --solver ("" when neither is given)."""
    keys = (["out_of_core = true"] if args.out_of_core else []) + ([f'solver = "{args.solver}"'] if args.solver else [])
    return "[fem]\n" + "\n".join(keys) + "\n" if keys else ""


class TreeMemory(threading.Thread):
    """Largest sum of the proportional set sizes of a process and its descendants, bytes,
    sampled every `every` s from /proc (Linux)."""

    def __init__(self, pid: int, every: float = 0.5):
        super().__init__(daemon=True)
        self.pid, self.every, self.peak = pid, every, 0
        self._done = threading.Event()

    def _tree(self) -> list[int]:
        children: dict[int, list[int]] = {}
        for d in os.listdir("/proc"):
            if d.isdigit():
                try:
                    ppid = int(Path(f"/proc/{d}/stat").read_text().rsplit(")", 1)[1].split()[1])
                except (OSError, IndexError, ValueError):
                    continue
                children.setdefault(ppid, []).append(int(d))
        out, todo = [], [self.pid]
        while todo:
            p = todo.pop()
            out.append(p)
            todo.extend(children.get(p, []))
        return out

    def _pss(self, pid: int) -> int:
        try:
            for line in Path(f"/proc/{pid}/smaps_rollup").read_text().splitlines():
                if line.startswith("Pss:"):
                    return 1024 * int(line.split()[1])
        except (OSError, ValueError):
            pass
        return 0

    def run(self):
        while not self._done.wait(self.every):
            self.peak = max(self.peak, sum(self._pss(p) for p in self._tree()))

    def stop(self):
        self._done.set()
        self.join()


def steps(deck: Path, out_of_core: bool = False, solver: str | None = None):
    """The same chain in this process, step by step, with the peak memory after each."""
    from fem.analysis import analyse_blade
    from fem.material import Material
    from fem.options import FemOptions
    from mesh.imported import import_blade
    from mesh.options import BladeOptions, MeshOptions
    from rom.craig_bampton import build_craig_bampton
    from rom.options import RomOptions

    def peak():
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 / 1e9  # kB -> GB

    t = time.perf_counter()
    m = import_blade(BladeOptions(mesh=deck.name, units="mm"), MeshOptions(), deck)
    print(f"import: {m.n_nodes} tet10 nodes, {len(m.cells)} cells, {time.perf_counter() - t:.1f} s, "
          f"peak {peak():.2f} GB; volume {m.volume:.6e} m^3, file's elements {m.reference_volume:.6e} m^3", flush=True)
    timings = {}
    options = FemOptions(out_of_core=out_of_core, **({"solver": solver} if solver else {}))
    fem = analyse_blade(m, Material(), options, timings)  # as the fem stage: assembly, factor, modes, basis
    print("; ".join(f"{k} {v:.1f}" if isinstance(v, float) else f"{k} {v}" for k, v in timings.items())
          + f"; peak {peak():.2f} GB", flush=True)
    t = time.perf_counter()
    rom = build_craig_bampton(fem, m, RomOptions())
    print(f"ROM {time.perf_counter() - t:.1f} s, peak {peak():.2f} GB; full-model Hz "
          + " ".join(f"{f:.1f}" for f in fem.frequencies_hz[:6]) + "; ROM Hz "
          + " ".join(f"{f / 2 / np.pi:.1f}" for f in rom.frequencies[:6]), flush=True)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--boxes", action="store_true")
    p.add_argument("--rotor67", action="store_true")
    p.add_argument("--size", type=float, default=0.0014, help="triangle size of the 2-D section mesh, m")
    p.add_argument("--layers", type=int, default=115, help="prism layers from hub to tip")
    p.add_argument("--out", default=str(ROOT / "out" / "bench_mesh_import"))
    p.add_argument("--until", default="rom")
    p.add_argument("--out-of-core", action="store_true", help="[fem] out_of_core = true in the scene")
    p.add_argument("--solver", default=None, help="[fem] solver in the scene: auto, cholmod or mumps")
    p.add_argument("--ranks", type=int, default=1, help="run under mpirun -n RANKS")
    p.add_argument("--deck-only", action="store_true", help="write the deck and the scene, do not run")
    p.add_argument("--steps", action="store_true", help="run import, assembly, FEM and ROM in this process, "
                   "printing the peak memory after each step, instead of bladerub run")
    args = p.parse_args(argv)
    if args.boxes:
        boxes()
    if args.rotor67:
        rotor67(args)


if __name__ == "__main__":
    main()
