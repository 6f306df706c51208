"""ParaView output: the blade's quadratic mesh with displacement fields as VTU files
(meshio's writer, binary and zlib-compressed), time series as a PVD collection.

Node order. The mesh keeps gmsh's tet10 ordering (mesh.model.BladeMesh: vertices, then
the mid-edge nodes of edges 01, 12, 20, 30, 32, 31); VTK's quadratic tetrahedron
(vtkQuadraticTetra) takes edges 01, 12, 20, 30, 31, 32: the last two are swapped. A file
written with gmsh's order opens in ParaView without complaint but draws (and
interpolates) every cell wrongly, so the cells are reordered here.
"""
from __future__ import annotations

import re
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from pipelines import artifacts as art

#: gmsh tet10 -> VTK tet10: VTK node k is gmsh node GMSH_TO_VTK_TET10[k].
GMSH_TO_VTK_TET10 = np.array([0, 1, 2, 3, 4, 5, 6, 7, 9, 8])


def require_finite(what: str, values) -> None:
    """Raise ValueError naming `what` when `values` ((n, ...) per node) holds NaN or inf:
    ParaView and VTK draw such a field without complaint, as garbage or nothing."""
    values = np.asarray(values)
    bad = ~np.isfinite(values)
    if bad.any():
        first = int(np.argwhere(bad)[0][0])
        raise ValueError(f"{what} holds {int(bad.sum())} non-finite value(s) (NaN or inf), the first at "
                         f"node {first}: refused, a picture or ParaView file of it would show garbage")


def _check_times(times: np.ndarray, count: int) -> None:
    """A series' times, s: `count` of them, finite and strictly increasing (ParaView orders
    and plays the steps by them)."""
    if times.ndim != 1 or len(times) != count:
        raise ValueError(f"times has shape {times.shape}; expected ({count},), one per snapshot")
    if not np.all(np.isfinite(times)):
        raise ValueError(f"times holds non-finite values: {times.tolist()}")
    steps = np.diff(times)
    if np.any(steps <= 0):
        i = int(np.argmax(steps <= 0))
        raise ValueError(f"times must increase strictly: times[{i}] = {times[i]!r} s, times[{i + 1}] = "
                         f"{times[i + 1]!r} s")


def write_vtu(path, nodes: np.ndarray, cells: np.ndarray, point_data: dict) -> Path:
    """Write the tet10 mesh with point fields to a VTU file, atomically.

    nodes: (n, 3), m. cells: (n_cells, 10), 0-based, gmsh tet10 ordering.
    point_data: {name: (n, 3) vectors or (n,) scalars}, SI units (displacements in m).
    (meshio 5's VTU writer drops field data, so what describes a file goes in its array
    names or in the PVD collection.) The connectivity is written as 32-bit integers when the
    node count allows (VTK reads either): zlib spends most of a file's time on it, and
    64-bit indices below 2^31 are half zeros (0.73 against 0.43 s per file on the default
    rotor 67 mesh).
    """
    import meshio

    cells = np.asarray(cells)
    if cells.ndim != 2 or cells.shape[1] != 10:
        raise ValueError(f"cells must be (n_cells, 10) tet10, got shape {cells.shape}")
    nodes = np.asarray(nodes, dtype=float)
    require_finite("nodes", nodes)
    for name, values in point_data.items():
        require_finite(f"point field {name!r}", values)
    index = np.int32 if len(nodes) < 2**31 else np.int64
    mesh = meshio.Mesh(nodes, [("tetra10", cells[:, GMSH_TO_VTK_TET10].astype(index))],
                       point_data={k: np.asarray(v) for k, v in point_data.items()})
    path = Path(path)
    with art.atomic_output(path) as tmp:
        meshio.write(tmp, mesh, file_format="vtu")
    return path


def write_pvd(path, entries, comment: str = "") -> Path:
    """A ParaView collection: entries [(time in s, VTU file)], times finite and strictly
    increasing, files relative to `path`'s folder; comment: a line of text kept in the file
    (what the series shows)."""
    path = Path(path)
    entries = list(entries)
    _check_times(np.array([float(t) for t, _ in entries]), len(entries))
    lines = ['<?xml version="1.0"?>'] + ([f"<!-- {comment.replace('--', '- -')} -->"] if comment else []) + [
             '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">', "  <Collection>"]
    for t, f in entries:
        rel = Path(f).relative_to(path.parent) if Path(f).is_absolute() else Path(f)
        lines.append(f'    <DataSet timestep="{float(t):.9e}" group="" part="0" file={quoteattr(rel.as_posix())}/>')
    lines += ["  </Collection>", "</VTKFile>", ""]
    with art.atomic_output(path) as tmp:
        tmp.write_text("\n".join(lines))
    return path


def mode_name(j: int, frequency_hz: float) -> str:
    """The point-array name of mode j (0-based) in modes.vtu: "mode_01 (439.04 Hz)"."""
    return f"mode_{j + 1:02d} ({frequency_hz:.2f} Hz)"


def write_mode_shapes(path, nodes, cells, modes: np.ndarray, frequencies_hz: np.ndarray) -> Path:
    """The first mode shapes as point vectors of one VTU, named by mode_name.

    modes: (k, n, 3) mass-normalised shapes at the nodes, kg^-1/2, float32 in the file (any
    normalisation: the shape is what ParaView's Warp By Vector shows). frequencies_hz: (k,).
    """
    modes = np.asarray(modes)
    data = {mode_name(j, f): modes[j].astype(np.float32) for j, f in enumerate(frequencies_hz[:modes.shape[0]])}
    return write_vtu(path, nodes, cells, data)


def remove_numbered(folder, prefix: str, width: int, suffix: str, first: int) -> list[Path]:
    """Remove folder's files f"{prefix}{i:0{width}d}{suffix}" for every i >= first: those an
    earlier, longer series of the same name left (ParaView's file dialog groups numbered files
    into one series, old frames among the new). Only names that exact pattern writes go; a
    user's own file beside them stays. Returns the paths removed."""
    folder = Path(folder)
    numbered = re.compile(re.escape(prefix) + r"(\d+)" + re.escape(suffix))
    removed = []
    for p in sorted(folder.iterdir()) if folder.is_dir() else ():
        m = numbered.fullmatch(p.name)
        if m and int(m[1]) >= first and p.name == f"{prefix}{int(m[1]):0{width}d}{suffix}" and not p.is_dir():
            p.unlink(missing_ok=True)
            removed.append(p)
    return removed


def write_time_series(folder, stem: str, nodes, cells, times: np.ndarray, displacement: np.ndarray,
                      comment: str = "") -> Path:
    """Displacement snapshots as folder/stem/stem_000.vtu ... and folder/stem.pvd.

    times: (N,), s (in the PVD), strictly increasing. displacement: (N, n, 3), m (point vectors
    "displacement", float32 in the files), finite. Both are checked before any file is
    written (ValueError), so a refused series leaves none. comment: kept in the PVD. Returns
    the PVD path.
    The snapshots are written by one thread per core: zlib, which takes most of a file's
    time, releases the GIL while it compresses.
    """
    import concurrent.futures
    import os

    times = np.asarray(times, dtype=float)
    displacement = np.asarray(displacement)
    _check_times(times, len(displacement))
    for i, snapshot in enumerate(displacement):
        require_finite(f"displacement at instant {i} (t = {times[i]:.6g} s)", snapshot)
    folder = Path(folder)
    sub = folder / stem
    sub.mkdir(parents=True, exist_ok=True)

    def write(i: int) -> Path:
        return write_vtu(sub / f"{stem}_{i:03d}.vtu", nodes, cells, {"displacement": displacement[i].astype(np.float32)})

    workers = max(1, min(len(os.sched_getaffinity(0)), len(times)))
    with concurrent.futures.ThreadPoolExecutor(workers) as pool:
        # map: when a write fails (a full disk), the snapshots not started yet are cancelled
        files = list(pool.map(write, range(len(times))))
    pvd = write_pvd(folder / f"{stem}.pvd", [(t, f.relative_to(folder)) for t, f in zip(times, files)], comment)
    remove_numbered(sub, f"{stem}_", 3, ".vtu", len(times))
    return pvd
