"""Test support: small Abaqus/CalculiX decks of a clamped slender box made by gmsh, and
CalculiX (ccx) as the independent reference for their frequencies.

The box, in the product's frame (z = rotation axis): radial length L along x from
R0 to R0 + L, chord b along z (centred on z = 0), thickness t along y (centred on y = 0).
The root face x = R0 is fixed in *BOUNDARY; the tip face x = R0 + L faces away from the
axis. gmsh meshes it: wedges by extruding a transfinite triangulation of the root face
(prisms), hexahedra by extruding a recombined one, second order with
Mesh.SecondOrderIncomplete = 1 (15- and 20-node elements). The deck's coordinates are in
the file's frame and unit: x_file = R^T x / scale for the axis and unit asked.
"""
from __future__ import annotations

import re
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

import numpy as np

# gmsh node order -> Abaqus/VTK (meshio's gmsh tables agree)
GMSH_TO_ABAQUS = {
    "wedge15": [0, 1, 2, 3, 4, 5, 6, 9, 7, 12, 14, 13, 8, 10, 11],
    "hexahedron20": [0, 1, 2, 3, 4, 5, 6, 7, 8, 11, 13, 9, 16, 18, 19, 17, 10, 12, 14, 15],
    "tetra10": [0, 1, 2, 3, 4, 5, 6, 7, 9, 8],
}
GMSH_TYPE = {"wedge15": 18, "hexahedron20": 17, "tetra10": 11}
ABAQUS_TYPE = {"wedge15": "C3D15", "hexahedron20": "C3D20", "tetra10": "C3D10",
               "wedge": "C3D6", "hexahedron": "C3D8", "tetra": "C3D4"}
N_CORNERS = {"wedge15": 6, "hexahedron20": 8, "tetra10": 4}
EDGES = {  # Abaqus order: corner pairs of the mid-edge nodes
    "wedge15": [(0, 1), (1, 2), (2, 0), (3, 4), (4, 5), (5, 3), (0, 3), (1, 4), (2, 5)],
    "hexahedron20": [(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4),
                     (0, 4), (1, 5), (2, 6), (3, 7)],
}
AXIS_ROTATIONS = {  # product = R @ file (the same cyclic permutations as mesh.imported, written here again)
    "z": np.eye(3),
    "x": np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]),
    "y": np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]),
}
UNITS = {"m": 1.0, "mm": 1e-3, "cm": 1e-2}


@dataclass(frozen=True)
class Box:
    """A meshed box in the product frame (m): points (n, 3), cells (k, n_el) 0-based, Abaqus order."""

    kind: str
    points: np.ndarray
    cells: np.ndarray
    R0: float
    L: float
    b: float
    t: float


def box(kind: str, L=0.3, b=0.02, t=0.01, R0=0.2, n=(30, 2, 1), cone_deg=0.0, perturb=0.0, seed=0,
        msh: Path | None = None) -> Box:
    """Mesh the box with gmsh: kind "wedge15" or "hexahedron20"; n = divisions (length,
    chord, thickness). cone_deg tilts the root face in the x-z plane (x = R0 + tan * z at the
    root, blended to the flat tip): a root that is not at a constant radius. perturb moves
    the corner nodes by up to perturb x the element size inside the box (the box's faces
    stay planar; the mid-edge nodes stay at edge midpoints). msh: also write gmsh's own
    .msh file of the plain box, with physical groups BLADE (volume) and ROOT (root face)."""
    import gmsh

    nl, nb, nt = n
    gmsh.initialize(["-noenv"])
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("box")
        geo = gmsh.model.geo
        p = [geo.addPoint(R0, y, z) for y, z in ((-t / 2, -b / 2), (t / 2, -b / 2), (t / 2, b / 2), (-t / 2, b / 2))]
        lines = [geo.addLine(p[i], p[(i + 1) % 4]) for i in range(4)]
        surf = geo.addPlaneSurface([geo.addCurveLoop(lines)])
        for i, c in enumerate(lines):
            geo.mesh.setTransfiniteCurve(c, (nt if i % 2 == 0 else nb) + 1)
        geo.mesh.setTransfiniteSurface(surf, "Alternate")
        if kind == "hexahedron20":
            geo.mesh.setRecombine(2, surf)
        ext = geo.extrude([(2, surf)], L, 0, 0, numElements=[nl], recombine=True)
        geo.synchronize()
        if msh is not None:
            gmsh.model.setPhysicalName(3, gmsh.model.addPhysicalGroup(3, [t for d, t in ext if d == 3]), "BLADE")
            gmsh.model.setPhysicalName(2, gmsh.model.addPhysicalGroup(2, [surf]), "ROOT")
        gmsh.option.setNumber("Mesh.ElementOrder", 2)
        gmsh.option.setNumber("Mesh.SecondOrderIncomplete", 1)
        gmsh.model.mesh.generate(3)
        tags, coords, _ = gmsh.model.mesh.getNodes()
        _, enodes = gmsh.model.mesh.getElementsByType(GMSH_TYPE[kind])
        if msh is not None:
            gmsh.write(str(msh))
    finally:
        gmsh.finalize()
    x = np.asarray(coords).reshape(-1, 3)
    index = np.full(int(np.max(tags)) + 1, -1, dtype=np.int64)
    index[np.asarray(tags, dtype=np.int64)] = np.arange(len(tags))
    width = 20 if kind == "hexahedron20" else 15
    cells = index[np.asarray(enodes, dtype=np.int64)].reshape(-1, width)[:, GMSH_TO_ABAQUS[kind]]
    used = np.unique(cells)
    renum = np.full(len(x), -1, dtype=np.int64)
    renum[used] = np.arange(len(used))
    x, cells = x[used].copy(), renum[cells]
    if perturb:
        h = np.array([L / nl, t / nt, b / nb])
        lo, hi = np.array([R0, -t / 2, -b / 2]), np.array([R0 + L, t / 2, b / 2])
        corners = np.unique(cells[:, :N_CORNERS[kind]])
        inside = (np.abs(x[corners] - lo) > 1e-9) & (np.abs(x[corners] - hi) > 1e-9)
        rng = np.random.default_rng(seed)
        x[corners] += inside * rng.uniform(-perturb, perturb, (len(corners), 3)) * h
        for j, (a, c) in enumerate(EDGES[kind]):
            x[cells[:, N_CORNERS[kind] + j]] = 0.5 * (x[cells[:, a]] + x[cells[:, c]])
    if cone_deg:
        s = (x[:, 0] - R0) / L
        x[:, 0] += (1.0 - s) * np.tan(np.radians(cone_deg)) * x[:, 2]
    return Box(kind, x, cells, R0, L, b, t)


def root_nodes(bx: Box, cone_deg: float = 0.0) -> np.ndarray:
    """Indices of the nodes on the root face (x = R0 + tan * z)."""
    x = bx.points
    return np.flatnonzero(np.abs(x[:, 0] - bx.R0 - np.tan(np.radians(cone_deg)) * x[:, 2]) < 1e-9 * bx.L)


def deck_ids(n: int, id_offset: int = 1000) -> np.ndarray:
    """Node ids write_deck gives n nodes: 1-based positions + id_offset, with a gap of 7 in
    the middle (so that ids are not positions)."""
    ids = id_offset + 1 + np.arange(n)
    ids[n // 2:] += 7
    return ids


def write_deck(path: Path, bx: Box, axis: str = "z", units: str = "m", root: np.ndarray | None = None,
               boundary: bool = True, material=None, n_modes: int = 0, id_offset: int = 1000,
               kind: str | None = None, extra: str = "", digits: int = 16) -> np.ndarray:
    """Write the box as an .inp deck, node ids by deck_ids. root: node indices of NSET=ROOT (fixed in *BOUNDARY if
    `boundary`). material: (E Pa, nu, rho kg/m^3) and n_modes > 0 add a *FREQUENCY step
    for CalculiX, in the deck's consistent unit system (length unit, N, s). kind: write the
    element type under another name (e.g. the linear one, with the corners only). digits:
    decimals of the coordinates (CalculiX reads 20 columns per number: give it 12).
    Returns the node ids."""
    scale = UNITS[units]
    xf = (bx.points @ AXIS_ROTATIONS[axis]) / scale  # R^T x for row vectors
    ids = deck_ids(len(xf), id_offset)
    kind = kind or bx.kind
    cells = bx.cells if kind == bx.kind else bx.cells[:, :N_CORNERS[bx.kind]]
    lines = ["*HEADING", f"bladerub test box, {bx.kind}, axis {axis}, {units}", "*NODE, NSET=NALL"]
    f = f"{{:.{digits}e}}"
    lines += [f"{i}, {f.format(a)}, {f.format(b)}, {f.format(c)}" for i, (a, b, c) in zip(ids, xf)]
    lines.append(f"*ELEMENT, TYPE={ABAQUS_TYPE[kind]}, ELSET=EALL")
    for e, row in enumerate(ids[cells], 1):
        vals = [str(e)] + [str(v) for v in row]
        chunks = [vals[i:i + 16] for i in range(0, len(vals), 16)]
        lines += [", ".join(c) + ("," if k < len(chunks) - 1 else "") for k, c in enumerate(chunks)]
    if root is not None:
        lines.append("*NSET, NSET=ROOT")
        r = ids[np.asarray(root)]
        lines += [", ".join(str(v) for v in r[i:i + 8]) for i in range(0, len(r), 8)]
        if boundary:
            lines += ["*BOUNDARY", "ROOT, 1, 3"]
    if extra:
        lines.append(extra)
    if material is not None and n_modes:
        E, nu, rho = material
        lines += ["*MATERIAL, NAME=MAT", "*ELASTIC", f"{E * scale ** 2:.12e}, {nu}", "*DENSITY",
                  f"{rho * scale ** 4:.12e}", "*SOLID SECTION, ELSET=EALL, MATERIAL=MAT",
                  "*STEP", "*FREQUENCY", f"{n_modes}", "*END STEP"]
    Path(path).write_text("\n".join(lines) + "\n")
    return ids


def ccx_frequencies(deck: Path, workdir: Path) -> np.ndarray:
    """Eigenfrequencies (Hz) of the deck's *FREQUENCY step by CalculiX, parsed from its .dat.

    Fails (never skips) without ccx: .ci/install installs calculix-ccx."""
    exe = shutil.which("ccx")
    assert exe is not None, "CalculiX (ccx) not found: run .ci/install (Debian package calculix-ccx)"
    workdir = Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    job = workdir / "job.inp"
    shutil.copyfile(deck, job)
    run = subprocess.run([exe, "-i", "job"], cwd=workdir, capture_output=True, text=True, timeout=300,
                         env={"OMP_NUM_THREADS": "1", "PATH": "/usr/bin:/bin"})
    assert run.returncode == 0, f"ccx failed:\n{run.stdout[-2000:]}\n{run.stderr[-2000:]}"
    assert "error" not in run.stdout.lower(), run.stdout[-3000:]
    text = (workdir / "job.dat").read_text()
    block = text.split("E I G E N V A L U E   O U T P U T")[1]
    rows = re.findall(r"^\s*(\d+)\s+(\S+)\s+(\S+)\s+(\S+)\s+(\S+)\s*$", block, flags=re.M)
    return np.array([float(r[3]) for r in rows])
