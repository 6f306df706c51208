"""A scene key that a stage's computation never reads does not enter its hash: changing it
leaves the folder's artifacts current, where a key it reads still reruns the stage.

Before, a scene importing its mesh file hashed the geometry table's keys ([blade] format,
hub_section, tip_section, every [mesh] key), and a DLFT-only isola search RL's [contact]
kappa, gamma and lanczos: changing one reran the mesh and everything after it (the FEM
alone ~1.5 min on the default blade), or the isola search (minutes), for the same results.
The reference for what is read: the import run on a scene that records its reads
(test_stage_dependencies.recording_scene), and the DLFT residual likewise.
"""
import json

import h5py
import numpy as np
import pytest

from decks import box, root_nodes, write_deck
from mesh.imported import import_blade
from pipelines.cli import main
from pipelines.runner import expected_inputs, plan
from pipelines.scene import load_scene
from pipelines.stages import REGISTRY
from test_stage_dependencies import recording_scene, result_keys

#: Keys the import of a mesh file never reads: the geometry table's and its meshing's.
TABLE_KEYS = ("mesh.element_size=0.01", "mesh.edge_layers=3", "mesh.size_growth=0.7", "blade.format=rotor37",
              "blade.hub_section=2", "blade.tip_section=10")
#: RL's own [contact] keys (pipelines.stages.hbm.nfrc_output("rl").depends).
RL_KEYS = ("contact.kappa=2e6", "contact.gamma=0.5", "contact.lanczos=false")


def _scene_text(contact_nodes=None) -> str:
    listed = f"contact_nodes = {list(contact_nodes)}\n" if contact_nodes is not None else ""
    return (f'[blade]\nmesh = "blade.inp"\nunits = "m"\n{listed}[mesh]\nn_boundary = 3\n'
            "[render]\nn_modes = 0\n")


@pytest.fixture(scope="module")
def imported(tmp_path_factory):
    """(scene path, output folder) of a wedge15 box deck taken through mesh and fem, and the
    deck ids of the 3 contact nodes the import chose."""
    d = tmp_path_factory.mktemp("imported")
    bx = box("wedge15", n=(8, 3, 2), perturb=0.3)
    write_deck(d / "blade.inp", bx, root=root_nodes(bx))
    (d / "scene.toml").write_text(_scene_text())
    assert main(["run", str(d / "scene.toml"), "--out", str(d), "--until", "fem", "--quiet"]) == 0
    with h5py.File(d / "mesh.h5", "r") as h5:
        ids = h5["source_node_ids"][()][h5["boundary_node_index"][()]]
    return d / "scene.toml", d, [int(i) for i in ids]


def _declared(scene) -> set[str]:
    stage = REGISTRY["mesh"]
    output, = stage.outputs(scene)
    return set(stage.depends + output.depends)


@pytest.mark.parametrize("listed", [False, True])
def test_the_mesh_output_of_an_import_declares_exactly_the_keys_the_import_reads(imported, listed):
    """[blade] mesh itself is read for its path only: the file enters the hash by content."""
    scene_path, out, ids = imported
    scene_path.with_name("listed.toml").write_text(_scene_text(ids))
    scene = load_scene(scene_path.with_name("listed.toml") if listed else scene_path)
    recorded, reads = recording_scene(scene)
    import_blade(recorded.blade, recorded.mesh, scene.resolve(scene.blade.mesh))
    assert result_keys(reads) - {"blade.mesh"} == _declared(scene)
    assert ("mesh.n_boundary" in _declared(scene)) == (not listed)


@pytest.mark.parametrize("key", TABLE_KEYS)
def test_a_table_key_leaves_an_imported_mesh_and_its_fem_current(imported, key):
    scene_path, out, _ = imported
    steps = plan(load_scene(scene_path, [key]), out, ("mesh", "fem"))
    assert [s.why for s in steps] == ["up to date", "up to date"]


@pytest.mark.parametrize("key", ["mesh.n_boundary=4", "blade.units=mm", "blade.root=hub", "blade.axis=x"])
def test_a_key_the_import_reads_reruns_it(imported, key):
    scene_path, out, _ = imported
    mesh, fem = plan(load_scene(scene_path, [key]), out, ("mesh", "fem"))
    assert mesh.todo and key.split("=")[0] in mesh.why, mesh.why
    assert fem.todo and "mesh.h5" in fem.why


def test_listed_contact_nodes_make_n_boundary_unread(imported, tmp_path):
    """With [blade] contact_nodes the import takes those nodes; n_boundary no longer counts
    (and listing the nodes it chose is another input: the mesh is made again)."""
    scene_path, out, ids = imported
    scene = tmp_path / "scene.toml"
    scene.write_text(_scene_text(ids))
    (tmp_path / "blade.inp").symlink_to(scene_path.with_name("blade.inp"))
    assert main(["run", str(scene), "--out", str(tmp_path), "--until", "mesh", "--quiet"]) == 0
    with h5py.File(tmp_path / "mesh.h5", "r") as a, h5py.File(out / "mesh.h5", "r") as b:
        np.testing.assert_array_equal(a["boundary_node_index"][()], b["boundary_node_index"][()])
    for key in ("mesh.n_boundary=5",) + TABLE_KEYS:
        assert plan(load_scene(scene, [key]), tmp_path, ("mesh",))[0].why == "up to date", key


def test_a_table_scene_still_hashes_every_meshing_key():
    """The geometry table is meshed with all of them: each reruns the mesh stage."""
    from pathlib import Path

    base = Path(__file__).resolve().parents[2] / "scenes" / "rotor67_coarse.toml"
    h = expected_inputs(load_scene(base), ("mesh",))["mesh.h5"][1]
    for key in TABLE_KEYS + ("mesh.n_boundary=4", "blade.units=m"):
        assert expected_inputs(load_scene(base, [key]), ("mesh",))["mesh.h5"][1] != h, key


def _standin_isolas(scene, out) -> None:
    """An isolas.h5 carrying the scene and its inputs (all the plan reads with verify=False)."""
    inputs, h = expected_inputs(scene, ("isolas",))["isolas.h5"]
    with h5py.File(out / "isolas.h5", "w") as h5:
        h5.attrs["inputs_hash"], h5.attrs["inputs"] = h, json.dumps(inputs, sort_keys=True)
        h5.attrs["scene"] = scene.text


@pytest.mark.parametrize("methods, key, reruns", [("dlft", k, False) for k in RL_KEYS]
                         + [("dlft", "contact.epsilon=1e-3", True), ("dlft", "contact.mu=0.2", True)]
                         + [(m, k, True) for m in ("rl", "dlft,rl") for k in RL_KEYS])
def test_rl_keys_rerun_the_isola_search_only_where_rl_is_searched(tmp_path, methods, key, reruns):
    from pathlib import Path

    base = Path(__file__).resolve().parents[2] / "scenes" / "rotor67_coarse.toml"
    _standin_isolas(load_scene(base, [f"hbm.methods={methods}"]), tmp_path)
    step, = plan(load_scene(base, [f"hbm.methods={methods}", key]), tmp_path, ("isolas",), verify=False)
    assert bool(step.todo) == reruns, step.why
    if reruns:
        assert key.split("=")[0] in step.why, step.why


def test_the_dlft_residual_reads_no_rl_key(coarse_run):
    """The isola search's DLFT problem (hbm.isolas.harmonic.HbmProblem builds this residual):
    mu and epsilon only, never RL's penalty or its filter."""
    from hbm.harmonic.residual import build_residual
    from pipelines.stages.hbm import nfrc_output
    from pipelines.stages.rom import read_rom

    scene_path, out = coarse_run
    recorded, reads = recording_scene(load_scene(scene_path, ["hbm.methods=dlft"]))
    rom = read_rom(out)
    res = build_residual(rom, recorded.casing, recorded.contact, recorded.hbm, method="dlft")
    res(np.full(res.size, 1e-4), 2000.0)
    contact = {k for k in result_keys(reads) if k.startswith("contact.")}
    assert contact and not contact & set(nfrc_output("rl").depends), contact


@pytest.mark.parametrize("key", ["fem.solver=mumps", "fem.ordering=amd", "fem.out_of_core=true",
                                 "fem.solver=cholmod"])
def test_how_the_fem_factorises_leaves_it_current(imported, key):
    scene_path, out, _ = imported
    assert [s.why for s in plan(load_scene(scene_path, [key]), out, ("mesh", "fem"))] == ["up to date", "up to date"]


@pytest.mark.parametrize("key", ["fem.tol=1e-9", "fem.n_modes=8", "material.E=110e9"])
def test_what_the_fem_computes_reruns_it(imported, key):
    scene_path, out, _ = imported
    mesh, fem = plan(load_scene(scene_path, [key]), out, ("mesh", "fem"))
    assert not mesh.todo and fem.todo and key.split("=")[0] in fem.why, fem.why


@pytest.mark.parametrize("options", [dict(solver="mumps", ordering="amd"), dict(solver="mumps", ordering="qamd"),
                                     dict(solver="auto", out_of_core=True)])
def test_another_factorisation_gives_the_same_fem_to_round_off(imported, options):
    """What makes fem.h5 current for them: the folder's fem.h5 (CHOLMOD) again, to 1e-9 (the
    frequencies of another ordering agree to 1e-9 in test_stages; measured here 1.1e-10 at
    most, where [fem] tol 1e-10 -> 1e-12 moves the mode shapes by 1e-8 to 2e-7)."""
    import dataclasses

    from fem.analysis import analyse_blade
    from pipelines.stages.fem import read_fem
    from pipelines.stages.mesh import read_mesh

    scene_path, out, _ = imported
    scene, ref = load_scene(scene_path), read_fem(out)
    fem_options = dataclasses.replace(scene.fem, n_fixed_interface_modes=scene.fixed_interface_modes, **options)
    got = analyse_blade(read_mesh(out), scene.material, fem_options)
    np.testing.assert_allclose(got.frequencies_hz, ref.frequencies_hz, rtol=1e-9)
    np.testing.assert_allclose(got.fixed_interface_frequencies, ref.fixed_interface_frequencies, rtol=1e-9)
    for name in ("modes", "fixed_interface_modes", "constraint_modes"):
        a, b = (getattr(r, name) for r in (got, ref))
        if name == "modes":  # (n_modes, n_nodes, 3): one mode a column, as the others
            a, b = (m.reshape(len(m), -1).T for m in (a, b))
        a = a * np.sign(np.sum(a * b, axis=0))  # an eigenvector's sign is arbitrary
        assert np.abs(a - b).max() <= 1e-9 * np.abs(b).max(), name


def test_the_fem_stage_stores_the_ordering_applied_and_says_when_it_is_not_the_one_asked(imported, tmp_path, capsys):
    """[fem] ordering, with [fem] solver = "mumps": METIS is not in Debian's MUMPS, which
    then takes its own choice: fem.h5 says which ran, and the log warns exactly when it
    differs from the scene's (that AMD is applied as asked: tests/fem/test_assembly.py).
    With the default solver (CHOLMOD, one process) an ordering asked for is noted as MUMPS's."""
    from fem.cholesky import CHOLMOD_ORDERING
    from pipelines import artifacts as art
    from support import fresh_copy

    scene_path, base, _ = imported
    for solver, asked in (("mumps", "metis"), ("auto", "amd")):
        out = fresh_copy(base, tmp_path / f"{solver}-{asked}")
        (out / "fem.h5").unlink()  # the factorisation's keys leave a current fem.h5 current (runner.HOW_NOT_WHAT)
        capsys.readouterr()
        assert main(["run", str(out / scene_path.name), "--out", str(out), "--until", "fem",
                     "--set", f"fem.ordering={asked}", "--set", f"fem.solver={solver}"]) == 0
        printed = capsys.readouterr().out
        attrs = art.read_attrs(out / "fem.h5")
        applied = attrs["ordering"]
        assert attrs["solver"] == ("cholmod" if solver == "auto" else solver)
        if solver == "auto":
            assert applied == CHOLMOD_ORDERING
            assert f'[fem] ordering = "{asked}" is MUMPS\'s; CHOLMOD factorised K' in printed, printed
            assert "WARNING" not in printed
        else:
            if asked == "amd":
                assert applied == "amd"
            warned = f'[fem] ordering = "{asked}" is not in this MUMPS build; it used {applied}' in printed
            assert warned == (applied != asked), (asked, applied, printed)
        with h5py.File(base / "fem.h5") as a, h5py.File(out / "fem.h5") as b:  # another order, the same modes
            np.testing.assert_allclose(b["frequencies"][:6], a["frequencies"][:6], rtol=1e-9)
