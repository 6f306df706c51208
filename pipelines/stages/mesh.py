"""Stage mesh: geometry table -> gmsh tet10 mesh of the blade, or the user's own mesh file
imported and split into tet10 (mesh.h5)."""
from __future__ import annotations

from pipelines import artifacts as art
from pipelines.stages.base import Context, Output, Stage

MESH = Output("mesh.h5")


def read_mesh(out):
    """The BladeMesh of an output folder."""
    from mesh.model import BladeMesh

    return art.read_artifact(out / MESH.file, BladeMesh)


# what an imported mesh depends on beyond the table keys (a table scene's hash is unchanged)
IMPORTED = Output(MESH.file, depends=("blade.axis", "blade.root", "blade.contact_nodes"))


def _compute(ctx: Context, outputs) -> None:
    from mesh.blade import mesh_blade
    from mesh.imported import import_blade

    scene = ctx.scene
    with ctx.progress.step("mesh", None) as update:
        if scene.blade.mesh is not None:
            update(f"importing {scene.blade.mesh}, split into tet10")
            result = import_blade(scene.blade, scene.mesh, scene.resolve(scene.blade.mesh))
            reference = "file's elements"
        else:
            update("gmsh: solid, surface and volume mesh")
            result = mesh_blade(scene.blade, scene.mesh, scene.resolve(scene.blade.geometry))
            reference = "section integral"
    output = outputs[0]
    art.write_artifact(ctx.out / MESH.file, result, **ctx.provenance(output, "mesh"))
    ctx.log(f"  {result.n_nodes} nodes, {len(result.cells)} tet10 cells, volume {result.volume:.4e} m^3 "
            f"({reference} {result.reference_volume:.4e} m^3)")


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


STAGE = Stage("mesh", depends=("blade.format", "blade.units", "blade.hub_section", "blade.tip_section", "mesh"),
              upstream=(), outputs=lambda scene: (IMPORTED if scene.blade.mesh is not None else MESH,),
              compute=_compute, files=_source)
