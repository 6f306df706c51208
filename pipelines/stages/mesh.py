"""Stage mesh: geometry table -> gmsh tet10 mesh of the blade (mesh.h5)."""
from __future__ import annotations

from pipelines import artifacts as art
from pipelines.stages.base import Context, Output, Stage

MESH = Output("mesh.h5")


def read_mesh(out):
    """The BladeMesh of an output folder."""
    from mesh.model import BladeMesh

    return art.read_artifact(out / MESH.file, BladeMesh)


def _compute(ctx: Context, outputs) -> None:
    from mesh.blade import mesh_blade

    scene = ctx.scene
    with ctx.progress.step("mesh", None) as update:
        update("gmsh: solid, surface and volume mesh")
        result = mesh_blade(scene.blade, scene.mesh, scene.resolve(scene.blade.geometry))
    art.write_artifact(ctx.out / MESH.file, result, **ctx.provenance(MESH, "mesh"))
    ctx.log(f"  {result.n_nodes} nodes, {len(result.cells)} tet10 cells, volume {result.volume:.4e} m^3 "
            f"(section integral {result.reference_volume:.4e} m^3)")


def _geometry(scene) -> dict:
    # the table enters by content, not by how its path is written
    path = scene.resolve(scene.blade.geometry)
    if not path.is_file():
        raise FileNotFoundError(f"geometry file not found: {path} (from [blade] geometry in {scene.path})")
    return {"geometry": path}


STAGE = Stage("mesh", depends=("blade.format", "blade.units", "blade.hub_section", "blade.tip_section", "mesh"),
              upstream=(), outputs=lambda scene: (MESH,), compute=_compute, files=_geometry)
