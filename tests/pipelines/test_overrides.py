"""A cheap coarse rotor 67 scene through every stage (from the session's coarse run to the
ROM, tests/pipelines/conftest.py), then:
`--set` overrides rerun exactly the stages that depend on the key (asserted from the run's
own report), a misspelt key is refused and writes nothing, `show` round-trips, and the
ParaView files of the run read back with the fields the artifacts hold."""
import shutil
from pathlib import Path

import meshio
import numpy as np
import pytest

from pipelines import artifacts as art
from pipelines.cli import main
from pipelines.runner import run_scene
from pipelines.scene import SECTIONS, load_scene, parse_scene

ROOT = Path(__file__).resolve().parents[2]
STAGES = ("mesh", "fem", "rom", "hbm", "ti", "validation")

# A short NFRC (N_h = 5 over [1900, 2000] rad/s) and a two-speed sweep of 10 revolutions:
# every stage runs, in seconds once the coarse mesh -> ROM is done.
CHEAP = """
[hbm]
methods = ["dlft"]
n_harmonics = 5
n_time = 64
omega_min = 1900.0
omega_max = 2000.0

[ti]
n_omega = 2
n_revolutions = 10
n_keep = 5
omega_min = 1900.0
omega_max = 2000.0

[render]
n_modes = 2
hbm_instants = 8
"""


def _scene_text(coarse_scene: Path) -> str:
    text = coarse_scene.read_text()
    for section in ("[hbm]", "[ti]", "[render]"):  # replaced by CHEAP's
        start = text.index(section)
        nxt = text.find("\n[", start + 1)
        text = text[:start] + (text[nxt + 1:] if nxt >= 0 else "")
    if "rotation" not in text:  # the time integration turns blades towards +theta only, for now
        text = text.replace("[blade]\n", '[blade]\nrotation = "+"\n')
    return text + CHEAP


@pytest.fixture(scope="module")
def base(tmp_path_factory, coarse_run):
    d = tmp_path_factory.mktemp("overrides")
    scene = d / "scene.toml"
    scene.write_text(_scene_text(coarse_run[0]))
    out = _copy(coarse_run[1], d / "base")  # its mesh and fem are this scene's too
    progress = run_scene(load_scene(scene), out)
    assert [r.stage for r in progress.records if not r.stage.startswith("figure")] == list(STAGES)
    return scene, out


def _copy(out: Path, dest: Path) -> Path:
    shutil.copytree(out, dest, symlinks=True)
    return dest


def _actions(progress) -> dict:
    return {r.stage: r.action for r in progress.records if r.stage in STAGES}


def test_set_mu_reruns_only_what_uses_mu(base, tmp_path, capsys):
    scene, out = base
    d = _copy(out, tmp_path / "mu")
    capsys.readouterr()
    assert main(["run", str(scene), "--out", str(d), "--set", "contact.mu=0.1"]) == 0
    printed = capsys.readouterr().out
    for s in ("mesh", "fem", "rom"):
        assert f"[{s}] up to date" in printed
    for s in ("hbm", "ti", "validation"):
        assert f"[{s}] running (inputs changed: contact" in printed, printed
    # the artifacts record the resolved scene with the override
    text = art.read_attrs(d / "nfrc_dlft.h5")["scene"]
    assert "--set contact.mu=0.1" in text and parse_scene(text).contact.mu == 0.1
    assert art.read_attrs(d / "rom.h5")["scene"] == scene.read_text()  # not rerun: the file's own text


def test_set_young_modulus_reruns_from_fem_on(base, tmp_path):
    scene, out = base
    d = _copy(out, tmp_path / "E")
    progress = run_scene(load_scene(scene, ["material.E=110e9"]), d)
    assert _actions(progress) == {"mesh": "reused", **{s: "computed" for s in STAGES[1:]}}
    # and a second run with the same override reuses everything
    again = run_scene(load_scene(scene, ["material.E=110e9"]), d)
    assert set(_actions(again).values()) == {"reused"}
    # the stiffer blade: frequencies scale with sqrt(E) (same mesh, same density)
    import h5py

    with h5py.File(out / "fem.h5") as a, h5py.File(d / "fem.h5") as b:
        ratio = b["frequencies"][:6] / a["frequencies"][:6]
    np.testing.assert_allclose(ratio, np.sqrt(110e9 / 108e9), rtol=1e-8)


@pytest.mark.parametrize("item, message", [
    ("contact.muu=0.1", "unknown key 'muu' in [contact] (did you mean 'mu'?)"),
    ("material.E=stiff", "[material] E must be a number, got 'stiff'"),
    ("material.nu=0.5", "Poisson's ratio nu must lie in"),
    ("contakt.mu=0.1", "unknown section [contakt] (did you mean 'contact'?)"),
])
def test_bad_override_is_refused_and_nothing_is_written(base, tmp_path, capsys, item, message):
    scene, out = base
    before = {p: p.stat().st_mtime_ns for p in out.rglob("*")}
    fresh = tmp_path / "never"
    for d in (out, fresh):
        assert main(["run", str(scene), "--out", str(d), "--set", item]) == 2
        assert message in capsys.readouterr().err
    assert not fresh.exists()
    assert before == {p: p.stat().st_mtime_ns for p in out.rglob("*")}


def test_show_round_trips(base, capsys):
    scene, _ = base
    sets = ["contact.mu=0.2", "hbm.start=omega_min", "blade.rotation=-", 'hbm.methods=["rl"]']
    assert main(["show", str(scene), *sum((["--set", s] for s in sets), [])]) == 0
    text = capsys.readouterr().out
    shown = parse_scene(text, scene)
    expected = load_scene(scene, sets)
    for section in SECTIONS:
        assert getattr(shown, section) == getattr(expected, section), section
    assert (shown.contact.mu, shown.hbm.start, shown.blade.rotation, shown.hbm.methods) == \
        (0.2, "omega_min", "-", ("rl",))
    # every key written out, defaults included
    assert "max_points = 4000" in text and "ordering = \"metis\"" in text


def test_paraview_files_of_the_run(base):
    _, out = base
    import h5py

    from pipelines.branch_store import load_branch
    from pipelines.stages.hbm import chosen_point
    from pipelines.vtu import mode_name

    with h5py.File(out / "mesh.h5") as h5:
        nodes, bnodes, frames = h5["nodes"][()], h5["boundary_node_index"][()], h5["boundary_frames"][()]
    with h5py.File(out / "fem.h5") as h5:
        modes, freqs = h5["modes"][:2], h5["frequencies_hz"][:2]
    m = meshio.read(out / "figures" / "modes.vtu")
    np.testing.assert_array_equal(m.points, nodes)
    assert m.cells[0].type == "tetra10" and len(m.point_data) == 2
    for j in range(2):  # float32 in the file
        np.testing.assert_allclose(m.point_data[mode_name(j, freqs[j])], modes[j], rtol=0,
                                   atol=1e-6 * abs(modes[j]).max())
    # the HBM instants: the full field at the contact nodes is the NFRC's own boundary
    # solution (its stored harmonics, synthesised here) in each node's frame
    stored = load_branch(out / "nfrc_dlft.h5")
    i = chosen_point(stored, None)
    omega, xb = stored.branch.omega[i], stored.extras["harmonics"][i]  # (2 N_h + 1, 27), m
    import xml.etree.ElementTree as ET

    entries = ET.parse(out / "figures" / "hbm_dlft.pvd").getroot().findall("./Collection/DataSet")
    assert len(entries) == 8 and len(list((out / "figures" / "hbm_dlft").glob("*.vtu"))) == 8
    nh = (xb.shape[0] - 1) // 2
    for e in entries:
        vtu = meshio.read(out / "figures" / e.get("file"))
        np.testing.assert_array_equal(vtu.points, nodes)
        tau = omega * float(e.get("timestep"))
        k = np.arange(1, nh + 1)
        local = xb[0] + np.cos(k * tau) @ xb[1::2] + np.sin(k * tau) @ xb[2::2]  # (27,) r, theta, z per node
        expected = np.einsum("jlx,jl->jx", frames, local.reshape(-1, 3))  # global x, y, z
        got = vtu.point_data["displacement"][bnodes]
        # the recovery matrix and the file hold float32 (relative round-off 6e-8; at a contact
        # node the recovery is the node's frame, the fixed-interface modes vanish there): 1e-6
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-6 * abs(expected).max())
