"""The cost estimates (the size guard) count the contact nodes the blade will have: those
[blade] contact_nodes lists for a mesh file, where [mesh] n_boundary does not apply (the
import never reads it). Before, every estimate read n_boundary, so 20 listed nodes beside
the default n_boundary = 9 were costed as 9: the HBM's unknowns, memory and disk ~2.2 times
too low, its dense terms ~5 times."""
import pytest

from decks import box, root_nodes, write_deck
from pipelines.scene import parse_scene
from pipelines.stages import REGISTRY

N_H, N_TIME, MAX_POINTS = 12, 256, 400
HBM = f'[hbm]\nn_harmonics = {N_H}\nn_time = {N_TIME}\nmax_points = {MAX_POINTS}\n'
STAGES = ("fem", "rom", "hbm", "isolas")


@pytest.fixture(scope="module")
def deck(tmp_path_factory):
    folder = tmp_path_factory.mktemp("deck")
    bx = box("wedge15", n=(8, 3, 2))
    ids = write_deck(folder / "blade.inp", bx, root=root_nodes(bx))
    assert len(ids) >= 20
    return folder, [int(i) for i in ids[-20:]]


def _scene(folder, text):
    path = folder / "scene.toml"
    return parse_scene(text + HBM, path)


def _estimates(scene, out):
    return {name: REGISTRY[name].estimate(scene, out, REGISTRY[name].outputs(scene)) for name in STAGES}


def _figures(est):
    return (est.memory, est.seconds, est.disk)


def _mesh_scene(folder, tail):
    return _scene(folder, '[blade]\nmesh = "blade.inp"\nunits = "m"\n' + tail)


def test_listed_contact_nodes_cost_as_many_as_n_boundary_would(deck, tmp_path):
    folder, ids = deck
    listed = _mesh_scene(folder, f"contact_nodes = {ids}\n[mesh]\nn_boundary = 9\n")
    assert listed.mesh.n_boundary == 9 and len(listed.blade.contact_nodes) == 20
    assert listed.n_contact_nodes == 20
    # the same deck, its 20 contact nodes snapped along the tip face
    snapped = _mesh_scene(folder, "[mesh]\nn_boundary = 20\n")
    got, want = _estimates(listed, tmp_path), _estimates(snapped, tmp_path)
    for name in STAGES:
        assert _figures(got[name]) == pytest.approx(_figures(want[name]), rel=1e-12), name


def test_listed_contact_nodes_cost_as_a_table_scene_with_as_many(deck, tmp_path):
    """The HBM and isola estimates do not depend on the mesh: a table scene with
    n_boundary = 20 costs the same as 20 listed nodes, and 9 costs the ratio of the
    formulas' terms at 3 x 9 and 3 x 20 boundary dof."""
    from pipelines.stages.hbm import AFT_BYTES

    folder, ids = deck
    listed = _mesh_scene(folder, f"contact_nodes = {ids}\n")
    assert listed.mesh.n_boundary == 9  # the default, which does not apply here
    table = {n: _scene(folder, f"[mesh]\nn_boundary = {n}\n") for n in (9, 20)}
    for name in ("hbm", "isolas"):
        got = REGISTRY[name].estimate(listed, tmp_path, REGISTRY[name].outputs(listed))
        want = REGISTRY[name].estimate(table[20], tmp_path, REGISTRY[name].outputs(table[20]))
        assert _figures(got) == pytest.approx(_figures(want), rel=1e-12), name

    hbm = REGISTRY["hbm"]
    outputs = hbm.outputs(listed)
    assert len(hbm.outputs(table[9])) == len(outputs)
    got, nine = hbm.estimate(listed, tmp_path, outputs), hbm.estimate(table[9], tmp_path, outputs)
    # per NFRC point: the n_c (3 n_b) harmonic unknowns, the n_c 3 n_b contact forces and 16 scalars
    n_c = 2 * N_H + 1
    stored = {n_b: 2 * n_c * 3 * n_b + 16 for n_b in (9, 20)}
    assert stored[20] / stored[9] == pytest.approx(2.2, abs=0.02)
    assert got.disk == pytest.approx(len(outputs) * MAX_POINTS * stored[20] * 8.0, rel=1e-12)
    assert got.disk / nine.disk == pytest.approx(stored[20] / stored[9], rel=1e-12)
    # memory: 0.2 GB, ten dense matrices of the unknowns, the AFT's signals, per treatment at once
    memory = {n_b: 0.2e9 + 10 * (n_c * 3 * n_b) ** 2 * 8.0 + AFT_BYTES * N_TIME * 3 * n_b for n_b in (9, 20)}
    assert got.memory / nine.memory == pytest.approx(memory[20] / memory[9], rel=1e-12)
    assert got.memory / nine.memory > 1.5


def test_the_isola_search_costs_its_points_as_the_nfrc_does(deck, tmp_path):
    """The isola search's seeds and branches are HBM points: its time estimate scales with the
    hbm stage's cost of a point, the AFT's at a large N_t included (2^20 samples of 27 boundary
    dof: ~34 s a point, against ~0.03 s at 256). It used to keep the harmonic term alone, and
    costed an N_t = 2^20 search as one at 256."""
    from pipelines.stages.hbm import point_seconds

    folder, _ = deck
    small, large = (parse_scene(f"[hbm]\nn_harmonics = {N_H}\nn_time = {n}\nmax_points = {MAX_POINTS}\n",
                                folder / "scene.toml") for n in (N_TIME, 2 ** 20))
    ratio = point_seconds(large) / point_seconds(small)
    assert ratio > 1000
    iso = REGISTRY["isolas"]
    est = [iso.estimate(s, tmp_path, iso.outputs(s)).seconds for s in (small, large)]
    assert est[1] / est[0] == pytest.approx(ratio, rel=1e-12)
