"""Stage mesh: geometry table -> gmsh tet10 mesh of the blade, or the user's own mesh file
imported and split into tet10 (mesh.h5).

Both run in a child process (pipelines.child): importing gmsh 4.8 sets SIGINT to its
default action, and its mesher holds the process for minutes, so Ctrl-C must be answered
by a parent that stays in Python.
"""
from __future__ import annotations

import functools

from pipelines import artifacts as art
from pipelines.stages.base import Context, Estimate, Output, Stage

#: what a geometry table is meshed with (mesh.blade.mesh_blade): the table's layout and
#: streamsurfaces, and every [mesh] key
MESH = Output("mesh.h5", depends=("blade.format", "blade.hub_section", "blade.tip_section", "mesh"))


def read_mesh(out):
    """The BladeMesh of an output folder."""
    from mesh.model import BladeMesh

    return art.read_artifact(out / MESH.file, BladeMesh)


def _imported(scene) -> Output:
    """What a mesh file is imported with (mesh.imported.import_blade): its axis, root and
    contact nodes, and [mesh] n_boundary only where the contact nodes are not listed; not the
    table's keys, nor [mesh] element_size, edge_layers or size_growth, which it never reads."""
    n_boundary = ("mesh.n_boundary",) if scene.blade.contact_nodes is None else ()
    return Output(MESH.file, depends=("blade.axis", "blade.root", "blade.contact_nodes") + n_boundary)


def _compute(ctx: Context, outputs) -> None:
    from mesh.blade import mesh_blade
    from mesh.imported import import_blade
    from pipelines.child import call_in_child
    from pipelines.guard import blade_warnings

    scene = ctx.scene
    with ctx.progress.step("mesh", None) as update:
        if scene.blade.mesh is not None:
            update(f"importing {scene.blade.mesh}, split into tet10")
            result = call_in_child(import_blade, scene.blade, scene.mesh, scene.resolve(scene.blade.mesh))
            reference = "file's elements"
            unit = scene.blade.units
        else:
            from mesh.geometry import read_geometry

            # the unit the table was read in: the scene's, or the one the table states
            table = read_geometry(scene.resolve(scene.blade.geometry), scene.blade.format, scene.blade.units)
            unit = table.units
            ctx.log(f"  table read in {unit}" + (f" (line {table.stated.line}: '{table.stated.text}')"
                                                 if table.stated is not None else " ([blade] units)"))
            update("gmsh: solid, surface and volume mesh")
            result = call_in_child(mesh_blade, scene.blade, scene.mesh, scene.resolve(scene.blade.geometry))
            reference = "section integral"
    output = outputs[0]
    art.write_artifact(ctx.out / MESH.file, result, **ctx.provenance(output, "mesh"))
    ctx.log(f"  {result.n_nodes} nodes, {len(result.cells)} tet10 cells, volume {result.volume:.4e} m^3 "
            f"({reference} {result.reference_volume:.4e} m^3)")
    for text in blade_warnings(scene, result.nodes, unit):
        ctx.progress.warn(text)


@functools.lru_cache(maxsize=8)
def _estimated_nodes(scene) -> float:
    """Nodes of the mesh the scene will make: from the table (mesh.estimate.estimate_nodes), or
    those of the file's split into tet10 (mesh.estimate.imported_nodes: the file is read, ~1 s
    for 170 000 nodes, where the import that follows reads it again and splits it)."""
    from mesh.estimate import estimate_nodes, imported_nodes
    from mesh.geometry import read_geometry

    b = scene.blade
    if b.mesh is not None:
        from mesh.source import read_source

        return float(imported_nodes(read_source(scene.resolve(b.mesh))))
    geometry = read_geometry(scene.resolve(b.geometry), b.format, b.units)
    sections = tuple(geometry.section(k) for k in range(b.hub_section, b.tip_section + 1))
    return estimate_nodes(sections, scene.mesh)


def node_count(scene, out) -> tuple[float, bool]:
    """(nodes, exact): from mesh.h5 when it is current for this scene, else estimated from the
    table (mesh.estimate, within ~30 %) or from the mesh file's elements (exact)."""
    import h5py

    from pipelines.runner import expected_inputs

    path = out / MESH.file
    if path.is_file() and art.read_attrs(path).get("inputs_hash") == expected_inputs(scene, ("mesh",))[MESH.file][1]:
        try:
            with h5py.File(path, "r") as h5:
                return float(h5["nodes"].shape[0]), True
        except (OSError, KeyError):
            pass
    return _estimated_nodes(scene), False


def coarser_mesh(scene) -> str:
    """The size guard's advice for a mesh too large for a later stage."""
    if scene.blade.mesh is not None:
        return f"import a coarser mesh than [blade] mesh = {scene.blade.mesh}"
    return f"coarsen [mesh] element_size (now {scene.mesh.element_size:g} m) or lower [mesh] edge_layers"


def nodes_text(n: float, exact: bool) -> str:
    from pipelines.guard import count

    return f"{count(n)} nodes" if exact else f"~{count(float(f'{n:.2g}'))} nodes (estimated)"


def _estimate(scene, out, outputs) -> Estimate | None:
    # measured on rotor 67 meshes of 24 000 to 197 000 nodes (2 cores, shared): 0.15-0.38 GB,
    # 9-70 s; gmsh's memory grows ~1.2 kB and its time ~0.15 ms per node (quiet machine)
    if scene.blade.mesh is not None:  # the gmsh figures below do not describe an import
        return None
    n = _estimated_nodes(scene)
    size, memory = nodes_text(n, False), 0.15e9 + 1.2e3 * n
    advice = (f"coarsen [mesh] element_size (now {scene.mesh.element_size:g} m; "
              "0.00145 m gives ~200 000 nodes on rotor 67) or lower [mesh] edge_layers")
    # the contact nodes: mesh.blade.nearest_nodes snaps n_b camber points to the tip face's
    # n_tip nodes through an (n_b, n_tip, 3) array of differences and its norms, ~7 doubles
    # per pair at its peak; the n_b nodes are distinct tip nodes, so n_tip >= n_b
    n_b = scene.mesh.n_boundary
    snap = 7 * 8.0 * float(n_b) ** 2
    if snap > memory:  # they, not the mesh, drive the memory
        from pipelines.guard import count

        size = f"{size}, {count(n_b)} contact nodes"
        advice = f"lower [mesh] n_boundary (now {n_b}; 9 in the reference scenes)"
    memory += snap
    return Estimate(size=size, memory=memory, seconds=5.0 + 1.5e-4 * n, disk=40.0 * n, advice=advice)


def _source(scene) -> dict:
    # the table or the mesh file (and its *INCLUDEs) enter by content, not by how the path is written
    from mesh.source import source_files

    key = "mesh" if scene.blade.mesh is not None else "geometry"
    path = scene.resolve(scene.blade.source)
    if not path.is_file():
        raise FileNotFoundError(f"{key} file not found: {path} (from [blade] {key} in {scene.path})")
    if key == "geometry":
        return {"geometry": path}
    return {("mesh" if i == 0 else f"mesh include {i}"): f for i, f in enumerate(source_files(path))}


# blade.units: the table's or the mesh file's length unit; the rest per source (MESH, _imported)
STAGE = Stage("mesh", depends=("blade.units",),
              upstream=(), outputs=lambda scene: (_imported(scene) if scene.blade.mesh is not None else MESH,),
              compute=_compute, files=_source, estimate=_estimate)
