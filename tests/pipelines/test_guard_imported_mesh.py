"""The size guard on a scene that imports its mesh: the tet10 node count of the file's split
is known before the import (mesh.estimate.imported_nodes), so the FEM and ROM stages are
checked before anything is computed, as for a table scene. Before, a mesh file had no
estimate at all and a deck too large for the machine went straight into the FEM."""
import pytest

from decks import box, root_nodes, write_deck
from mesh.estimate import imported_nodes
from mesh.imported import import_blade
from mesh.options import BladeOptions, MeshOptions
from mesh.source import read_source
from pipelines.cli import main


@pytest.mark.parametrize("kind", ["wedge15", "hexahedron20"])
def test_the_split_node_count_is_the_imports(kind, tmp_path):
    deck = tmp_path / "blade.inp"
    bx = box(kind, n=(8, 3, 2), perturb=0.3)
    write_deck(deck, bx, root=root_nodes(bx))
    split = import_blade(BladeOptions(mesh=deck.name, units="m"), MeshOptions(n_boundary=3), deck)
    # counted without splitting: the file's nodes, one per distinct quadrilateral face, one per hexahedron
    assert imported_nodes(read_source(deck)) == len(split.nodes) > len(bx.points)


def test_an_imported_mesh_too_large_for_the_memory_limit_is_refused_before_the_import(tmp_path, capsys):
    bx = box("wedge15", n=(12, 2, 1))
    write_deck(tmp_path / "blade.inp", bx, root=root_nodes(bx))
    scene = tmp_path / "scene.toml"
    scene.write_text('[blade]\nmesh = "blade.inp"\nunits = "m"\n[mesh]\nn_boundary = 3\n[render]\nn_modes = 0\n'
                     '[limits]\nmemory_gb = 0.05\n')
    out = tmp_path / "out"
    assert main(["run", str(scene), "--out", str(out), "--until", "fem"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("bladerub: error: [fem] ~380 nodes (estimated), ~1 125 dof would need ~"), err
    assert "more than [limits] memory_gb (50 MB): import a coarser mesh than [blade] mesh = blade.inp" in err
    assert not out.exists()
