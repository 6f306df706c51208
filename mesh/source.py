"""What a user's mesh file holds, in the file's own units and numbering.

Abaqus/CalculiX decks (.inp) are read by `mesh.abaqus` (meshio 5's reader gives no
*BOUNDARY and fails on C3D15 and on a second *NODE block, see there); every other format
(.msh, .med, .bdf, .vtu, .xdmf, ...) through meshio.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

QUADRATIC = ("tetra10", "wedge15", "hexahedron20")
LINEAR = {"tetra": "4-node tetrahedra", "wedge": "6-node wedges", "hexahedron": "8-node hexahedra"}
QUADRATIC_OF = {"tetra": "10-node tetrahedra", "wedge": "15-node wedges", "hexahedron": "20-node hexahedra"}


class MeshImportError(ValueError):
    """A mesh file that cannot be used as the blade, with what is wrong in it."""


@dataclass(frozen=True)
class SolidBlock:
    """Solid elements of one type.

    type: meshio cell type ("tetra10", "wedge15", ...) or, for a solid type bladerub does not
        know, the file's own name of it. connectivity: (k, n) 0-based node indices in
        VTK/Abaqus node order. ids: (k,) element ids as numbered in the file.
    where: the file and line of the first *ELEMENT block of the type ("blade.inp:57"), so a
        refusal can point at it; "" where the format has no such line (meshio files).
    """

    type: str
    connectivity: np.ndarray
    ids: np.ndarray
    where: str = ""


@dataclass(frozen=True)
class SourceMesh:
    """A mesh file's content.

    points: (n, 3) node coordinates, file units. node_ids: (n,) node ids as numbered in the
    file (for formats read through meshio: the file's own ids where meshio keeps them, the
    GRID ids of a Nastran .bdf; else the 1-based position in the node list).
    blocks: the solid elements. node_sets: set name (upper case for .inp) -> node indices.
    fixed: (n, 3) bool, translations the file fixes (*BOUNDARY), or None if the format
    carries no boundary conditions. ignored: element type -> count of non-solid elements
    skipped (surfaces, lines). files: the files read (source_files: a deck and its *INCLUDEs, ...).
    unknown_ids: set name -> node ids it names that the file does not define (left out of
    node_sets; refused where the set is used, e.g. as the root).
    """

    points: np.ndarray
    node_ids: np.ndarray
    blocks: tuple[SolidBlock, ...]
    node_sets: dict = field(default_factory=dict)
    fixed: np.ndarray | None = None
    ignored: dict = field(default_factory=dict)
    files: tuple[Path, ...] = ()
    unknown_ids: dict = field(default_factory=dict)


def read_source(path: Path) -> SourceMesh:
    """Read a mesh file (.inp by mesh.abaqus, anything else by meshio).

    Raises MeshImportError if the file is missing or cannot be read.
    """
    path = Path(path)
    if not path.is_file():
        raise MeshImportError(f"mesh file not found: {path}")
    if path.suffix.lower() == ".inp":
        from mesh.abaqus import read_deck

        return read_deck(path)
    return _read_meshio(path)


def source_files(path: Path) -> list[Path]:
    """The files a mesh file consists of (itself and, for a deck, its *INCLUDE files, for an
    XDMF file its heavy-data files): what the mesh stage's inputs hash covers."""
    path = Path(path)
    if path.suffix.lower() == ".inp":
        from mesh.abaqus import included_files

        return [path, *included_files(path)]
    if path.suffix.lower() in (".xdmf", ".xmf"):
        return [path, *xdmf_data_files(path)]
    return [path]


def xdmf_data_files(path: Path) -> list[Path]:
    """The HDF5 (and raw binary) files an XDMF file's DataItems name, relative to it, in
    order, each once: an .xdmf holds only the layout, its nodes and cells live there, so a
    changed .h5 must change the mesh stage's inputs. Files that do not exist are left out
    (reading the mesh then fails, by name)."""
    import xml.etree.ElementTree as ET

    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError) as exc:
        raise MeshImportError(f"cannot read {path} as XDMF: {exc}") from exc
    out = []
    for item in root.iter():
        if item.tag.rsplit("}", 1)[-1] != "DataItem" or item.get("Format", "XML").upper() not in ("HDF", "BINARY"):
            continue
        name = (item.text or "").strip().split(":", 1)[0]  # "blade.h5:/data0"
        f = Path(name) if Path(name).is_absolute() else path.parent / name
        if name and f.is_file() and f not in out:
            out.append(f)
    return out


def _register_wedge15():
    """meshio 5.0 maps gmsh, Abaqus, VTK, MED... 15-node wedges to its "wedge15" type but
    leaves it out of its table of topological dimensions, so building the Mesh fails with
    KeyError 'wedge15'. The table is meshio's (private) one; adding the missing entry is the
    smallest fix, and harmless where a newer meshio already has it."""
    from meshio import _mesh

    _mesh.topological_dimension.setdefault("wedge15", 3)


def _read_meshio(path: Path) -> SourceMesh:
    import meshio

    _register_wedge15()
    try:
        m = meshio.read(path)
    except Exception as exc:  # meshio raises ReadError, KeyError, ValueError... by format
        raise MeshImportError(f"meshio cannot read {path}: {type(exc).__name__}: {exc}") from exc
    points = np.asarray(m.points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise MeshImportError(f"{path}: nodes have {points.shape[1]} coordinates; a solid mesh needs 3")
    blocks, ignored, offset = [], {}, 0
    element_ids = _file_ids(m, "cells_id")
    for k, cb in enumerate(m.cells):
        ids = offset + 1 + np.arange(len(cb.data)) if element_ids is None else element_ids[k]
        offset += len(cb.data)
        if len(cb.data) == 0:
            continue  # an empty block: neither a type of the blade nor something skipped
        if cb.dim == 3:
            blocks.append(SolidBlock(cb.type, np.asarray(cb.data, dtype=np.int64), ids))
        else:
            ignored[cb.type] = ignored.get(cb.type, 0) + len(cb.data)
    sets = {name: np.unique(np.asarray(v, dtype=np.int64)) for name, v in m.point_sets.items()}
    # cell sets (gmsh physical groups, MED groups): their nodes, under the set's name
    for name, per_block in m.cell_sets.items():
        if name in sets or name.startswith("gmsh:"):
            continue
        nodes = [np.asarray(m.cells[i].data)[np.asarray(idx, dtype=np.int64)].ravel()
                 for i, idx in enumerate(per_block) if idx is not None and len(idx)]
        if nodes:
            sets[name] = np.unique(np.concatenate(nodes)).astype(np.int64)
    node_ids = _file_ids(m, "points_id")
    if node_ids is None or len(node_ids) != len(points) or len(np.unique(node_ids)) != len(points):
        node_ids = np.arange(1, len(points) + 1, dtype=np.int64)
    return SourceMesh(points=points, node_ids=node_ids, blocks=tuple(blocks), node_sets=sets, fixed=None,
                      ignored=ignored, files=tuple(source_files(path)))


def _file_ids(m, attribute: str):
    """The file's own node ids (attribute "points_id": an array) or element ids ("cells_id": one
    array per cell block) where meshio keeps them: in meshio 5, its Nastran reader only (GRID
    and element ids); None where it does not (every other format: ids are then positions)."""
    ids = getattr(m, attribute, None)
    if ids is None:
        return None
    if attribute == "cells_id":
        if len(ids) != len(m.cells) or any(len(i) != len(c.data) for i, c in zip(ids, m.cells)):
            return None
        return [np.asarray(i, dtype=np.int64) for i in ids]
    return np.asarray(ids, dtype=np.int64)
