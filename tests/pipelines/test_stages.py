"""Stages depend only on what they use, end to end on a tiny scene built on the coarse ROM.

The tiny scene keeps the coarse rotor 67 mesh, FEM and ROM (shared, session-wide) and runs
a cheap NFRC (N_h = 5, N_t = 64, Omega in [1900, 2000]) and a short TI sweep (2 speeds, 20
revolutions), then the validation stage (20 periods per point), the figures and `bladerub render`.
"""
import os
import re
from contextlib import contextmanager
from pathlib import Path

import h5py
import numpy as np
import pytest

from pipelines import artifacts as art
from pipelines.cli import main
from pipelines.progress import Progress
from pipelines.runner import run_scene
from pipelines.scene import load_scene, parse_scene
from support import fresh_copy

TINY = """
[hbm]
methods = ["dlft", "rl"]
n_harmonics = 5
n_time = 64
omega_min = 1900.0
omega_max = 2000.0

[ti]
dt = 4e-7
n_revolutions = 20
n_keep = 5
omega_min = 1900.0
omega_max = 2000.0
n_omega = 2

[isolas]
n_modes = 1
harmonics = [2]
amplitudes = [1e-3]
n_omega = 2

[validation]
n_periods = 20
n_candidates = 2
n_scan = 4
pd_points = 6
"""


def _scene(text: str, path):
    """The coarse scene with the [hbm] and [ti] sections replaced by TINY's."""
    start, end = text.index("[hbm]"), text.index("[render]")
    path.write_text(text[:start] + TINY + "\n" + text[end:])
    return path


class _Lines(Progress):
    """A quiet Progress that keeps the text of every live-line update, per step label."""

    def __init__(self):
        super().__init__(quiet=True)
        self.lines: dict[str, list[str]] = {}

    @contextmanager
    def step(self, label, total=None):
        kept = self.lines.setdefault(label, [])
        yield lambda text=None, completed=None: kept.append(text) if text is not None else None


def _records(scene_path, out, progress=None, **kw):
    """{stage: (action, why)} of one run."""
    progress = progress or Progress(quiet=True)
    run_scene(load_scene(scene_path), out, progress=progress, **kw)
    return {r.stage: (r.action, r.why) for r in progress.records}


@pytest.fixture(scope="module")
def tiny(coarse_run, tmp_path_factory):
    """A private folder with the coarse ROM, run through every stage once."""
    scene0, base = coarse_run
    out = fresh_copy(base, tmp_path_factory.mktemp("tiny"))
    scene = _scene(scene0.read_text(), out / "tiny.toml")
    progress = _Lines()
    rec = _records(scene, out, progress)
    assert rec["hbm"][0] == rec["ti"][0] == rec["validation"][0] == "computed"
    assert not list(out.glob("*.partial.h5"))  # each gone once its artifact holds everything
    if len(os.sched_getaffinity(0)) >= 2:  # the sweep ran beside the NFRCs (pipelines.runner)
        assert rec["ti"][1] == "no artifact (started beside hbm)", rec["ti"]
        # and the NFRCs' live line says how far it is once a treatment has ended
        shown = [t for t in progress.lines["hbm dlft + rl"] if "ended" in t]
        assert shown and all(re.search(r"; ti: \d+/2 speeds$", t) for t in shown), shown[-3:]
    return scene, out


def _stamps(out):
    return {p.name: p.stat().st_mtime_ns for p in out.glob("*.h5")}


def test_every_stage_and_figure_is_made(tiny):
    scene, out = tiny
    for name in ("nfrc_dlft.h5", "nfrc_rl.h5", "ti.h5", "validation.h5"):
        assert art.read_attrs(out / name)["created"], name
    figs = out / "figures"
    for png in ("nfrc.png", "ti_sweep.png", "validation_dlft.png", "validation_rl.png", "contact_dlft.png",
                "solution_set.png", "solution_set_rl.png", "mode_01.png"):
        assert (figs / png).stat().st_size > 10_000, png
    # every dataset of every artifact carries its unit (the NFRC files included)
    for name in ("nfrc_dlft.h5", "rom.h5", "validation.h5"):
        with h5py.File(out / name) as h5:
            missing = []
            h5.visititems(lambda k, obj: missing.append(k) if isinstance(obj, h5py.Dataset)
                          and "unit" not in obj.attrs and "unit" not in obj.parent.attrs else None)
        assert not missing, (name, missing[:5])


def test_the_sweep_run_beside_the_nfrcs_is_the_sweep_run_alone(tiny):
    """The sweep started beside the NFRCs (on the cores their processes free) gives, speed
    for speed, what one process marching the speeds in order gives."""
    from hbm.ti.sweep import sweep
    from pipelines.stages.rom import read_rom
    from pipelines.stages.ti import read_sweep

    scene_path, out = tiny
    scene = load_scene(scene_path)
    alone = sweep(read_rom(out), scene.casing, scene.contact, scene.ti, workers=1)
    beside = read_sweep(out)
    for name in ("omega", "amplitude", "period_class", "revolutions", "displacement", "normal_force", "sections"):
        np.testing.assert_array_equal(getattr(beside, name), getattr(alone, name), err_msg=name)


def test_a_second_run_reuses_everything(tiny):
    scene, out = tiny
    before = _stamps(out)
    rec = _records(scene, out)
    assert all(action == "reused" for action, _ in rec.values()), rec
    assert _stamps(out) == before


def _changed(tiny, tmp_path, old, new, until=None):
    """Run a copy of the tiny folder with one scene value changed (up to stage `until`, all
    by default); (records, names of the artifacts whose bytes changed, scene path)."""
    scene, base = tiny
    out = fresh_copy(base, tmp_path / "out")
    text = scene.read_text()
    assert old in text
    path = tmp_path / "changed.toml"
    path.write_text(text.replace(old, new, 1))
    before = {p.name: p.read_bytes() for p in out.glob("*.h5")}
    rec = _records(path, out, **({"until": until} if until else {}))
    after = {p.name: p.read_bytes() for p in out.glob("*.h5")}
    return rec, {k for k in before if before[k] != after[k]}, path


def _after_hbm(scene_path, out) -> dict:
    """{stage: why} of what a run would do next after the hbm stage (the runner's own plan;
    the stages after hbm run in full in the --set test below)."""
    from pipelines.runner import plan

    return {s.stage.name: s.why for s in plan(load_scene(scene_path), out, ("ti", "isolas", "validation"))}


def test_render_settings_never_recompute_the_fem(tiny, tmp_path):
    rec, changed, _ = _changed(tiny, tmp_path, "[render]\nn_modes = 2", "[render]\nn_modes = 3\nscale = 0.05")
    assert changed == set()  # no artifact touched
    assert rec["fem"][0] == "reused" and rec["figure modes"][0] == "computed"
    assert (tmp_path / "out" / "figures" / "mode_03.png").is_file()


def test_harmonics_rerun_the_hbm_but_never_the_sweep(tiny, tmp_path):
    rec, changed, path = _changed(tiny, tmp_path, "n_harmonics = 5", "n_harmonics = 4", until="hbm")
    assert changed == {"nfrc_dlft.h5", "nfrc_rl.h5"}
    # the reason names the key the scene changed and its two values, not the hashed part
    # of the scene the stage reads ("hbm except methods")
    assert rec["hbm"][1] == ("nfrc_dlft.h5: inputs changed: hbm.n_harmonics 5 -> 4; "
                             "nfrc_rl.h5: inputs changed: hbm.n_harmonics 5 -> 4"), rec["hbm"]
    nxt = _after_hbm(path, tmp_path / "out")
    assert nxt["ti"] == "up to date"
    # the search and the validation read the hbm section and the NFRCs: both out of date
    for s in ("isolas", "validation"):
        assert nxt[s].startswith("inputs changed: ") and "nfrc_dlft.h5" in nxt[s] and "nfrc_rl.h5" in nxt[s], nxt


def test_penalty_stiffness_reruns_rl_only(tiny, tmp_path):
    rec, changed, path = _changed(tiny, tmp_path, "kappa = 1e9", "kappa = 2e9", until="hbm")
    assert changed == {"nfrc_rl.h5"}
    assert rec["hbm"][1] == "nfrc_rl.h5: inputs changed: contact.kappa 1e+09 -> 2e+09", rec["hbm"]
    nxt = _after_hbm(path, tmp_path / "out")  # one isolas.h5 for both treatments: out of date
    assert nxt["ti"] == "up to date"
    for s in ("isolas", "validation"):
        assert nxt[s].startswith("inputs changed: ") and "nfrc_rl.h5" in nxt[s] and "nfrc_dlft.h5" not in nxt[s], nxt


def test_a_reason_without_the_artifacts_scene_names_what_the_stage_reads(tiny, tmp_path):
    """An artifact whose recorded scene cannot be read as one, or that has none (an older or
    edited file): the reason names the part of the scene that changed, as the stage reads it."""
    from pipelines.runner import plan

    scene, base = tiny
    out = fresh_copy(base, tmp_path / "out")
    for m, text in (("dlft", "not = [a scene"), ("rl", "")):  # unreadable, and none (parsed: the defaults)
        with h5py.File(out / f"nfrc_{m}.h5", "r+") as h5:
            h5.attrs["scene"] = text
    path = tmp_path / "changed.toml"
    path.write_text(scene.read_text().replace("n_harmonics = 5", "n_harmonics = 4", 1))
    why = {s.stage.name: s.why for s in plan(load_scene(path), out, ("hbm",))}
    assert why["hbm"] == ("nfrc_dlft.h5: inputs changed: hbm except methods; "
                          "nfrc_rl.h5: inputs changed: hbm except methods"), why


def test_the_nfrc_figure_reads_the_sweep_back(tiny):
    """nfrc.png overlays the TI sweep's points (Fig. 6): its recorded inputs include ti.h5."""
    from pipelines.runner import figure_hash
    from pipelines.stages.hbm import NFRC_FIGURE
    import json

    scene, out = tiny
    manifest = json.loads((out / "figures" / "manifest.json").read_text())
    with_ti = figure_hash(load_scene(scene), out, NFRC_FIGURE)
    assert manifest["nfrc"]["inputs"] == with_ti
    moved = out.parent / "ti_moved.h5"
    (out / "ti.h5").rename(moved)
    try:
        assert figure_hash(load_scene(scene), out, NFRC_FIGURE) != with_ti
    finally:
        moved.rename(out / "ti.h5")


def test_a_missing_figure_is_redrawn_without_recomputing(tiny, tmp_path):
    scene, base = tiny
    out = fresh_copy(base, tmp_path / "out")
    (out / "figures" / "nfrc.png").unlink()
    before = _stamps(out)
    rec = _records(scene, out)
    assert rec["figure nfrc"][0] == "computed" and (out / "figures" / "nfrc.png").is_file()
    assert all(rec[s][0] == "reused" for s in ("mesh", "fem", "rom", "hbm", "ti", "validation"))
    assert _stamps(out) == before


def test_an_artifact_computed_again_redraws_its_figures(tiny, tmp_path):
    """The NFRC files computed again from the same inputs (deleted here; --force or a newer
    code does the same): nfrc.png is drawn again from them, although every input hash is
    unchanged and the stages after hbm are reused."""
    scene, base = tiny
    out = fresh_copy(base, tmp_path / "out")
    for m in ("dlft", "rl"):
        (out / f"nfrc_{m}.h5").unlink()
    rec = _records(scene, out)
    assert rec["hbm"][0] == "computed"
    assert rec["figure nfrc"] == ("computed", "inputs changed: nfrc_dlft.h5 (recomputed), nfrc_rl.h5 (recomputed)")
    assert rec["ti"][0] == "reused"


def test_a_figure_says_which_input_changed(tiny, tmp_path):
    """The figure's reason names the scene keys and the artifacts that differ from those it
    was drawn from; a manifest of an older version, without them, says only 'inputs changed'."""
    import json

    from pipelines.runner import _figure_changes

    old = {"scene hbm": "a", "input nfrc_dlft.h5": "h1 t1", "input ti.h5": "absent ", "input isolas.h5": "h3 t3"}
    new = {"scene hbm": "b", "input nfrc_dlft.h5": "h1 t1", "input ti.h5": "h2 t2", "input isolas.h5": "absent "}
    assert _figure_changes(old, new) == "isolas.h5 (gone), ti.h5 (new), hbm"  # as the stages name it
    assert _figure_changes(old, old) == ""

    scene, base = tiny
    out = fresh_copy(base, tmp_path / "out")
    path = out / "figures" / "manifest.json"
    manifest = json.loads(path.read_text())
    for entry in manifest.values():  # as an older version wrote it
        entry.pop("components")
    path.write_text(json.dumps(manifest))
    for m in ("dlft", "rl"):
        (out / f"nfrc_{m}.h5").unlink()
    assert _records(scene, out)["figure nfrc"] == ("computed", "inputs changed")


def test_render_command(tiny, tmp_path, capsys):
    scene, base = tiny
    out = fresh_copy(base, tmp_path / "out")
    assert main(["render", str(scene), "--out", str(out), "--modes", "1"]) == 0
    assert (out / "figures" / "mode_01.png").is_file()
    # before the fem stage: one clear line naming the command to run, exit 2
    assert main(["render", str(scene), "--out", str(tmp_path / "empty")]) == 2
    err = capsys.readouterr().err
    assert "--until fem" in err and "Traceback" not in err


def test_a_missing_field_is_a_clear_error(tiny, tmp_path):
    from pipelines.stages.validation import ValidationArtifact

    scene, base = tiny
    out = fresh_copy(base, tmp_path / "out")
    with h5py.File(out / "validation.h5", "a") as h5:
        del h5["dlft"]["primary"]["ti"]["drift"]
    with pytest.raises(art.ArtifactError, match="field 'drift' of OrbitValidation is missing"):
        art.read_artifact(out / "validation.h5", ValidationArtifact)
    from rom.model import load_rom

    with h5py.File(out / "rom.h5", "a") as h5:
        del h5["K"]
    with pytest.raises(ValueError, match="dataset 'K' is missing"):
        load_rom(out / "rom.h5")
    assert np.isfinite(art.read_attrs(out / "rom.h5").get("n_lobes", 0.0))  # attributes still readable


# -- overrides from the command line (--set) and the resolved scene (show) -------------------

def test_a_massless_sweep_past_the_friction_lock_is_warned_about(tiny, tmp_path, capsys):
    """Above the ROM's mu_set a massless node kept in contact locks and the sweep's amplitude
    follows the step (README); the coarse ROM's mu_set is 0.123, the scene's mu 0.15."""
    from pipelines.stages.ti import massless_warning
    from rom.model import load_rom

    scene, base = tiny
    lock = load_rom(base / "rom.h5").friction_lock
    assert 0.12 < lock.mu_set < 0.13
    assert "mu_set = 0.123" in massless_warning("massless", 0.15, lock)
    assert massless_warning("massless", 0.1, lock) is None
    assert massless_warning("carpenter", 0.15, lock) is None and massless_warning("massless", 0.15, None) is None
    out = fresh_copy(base, tmp_path / "out")
    capsys.readouterr()
    assert main(["run", str(scene), "--out", str(out), "--until", "ti", "--set", "ti.scheme=massless"]) == 0
    printed = capsys.readouterr().out
    assert "[ti] running" in printed and "WARNING: [ti] scheme = massless with friction mu = 0.15 past" in printed


def test_set_young_modulus_reruns_from_the_fem_on(tiny, tmp_path):
    from pipelines.runner import plan

    scene, base = tiny
    out = fresh_copy(base, tmp_path / "out")
    sets = ["material.E=110e9"]
    rec = _records_with(scene, out, sets, until="rom")  # the stages after the ROM: checked below
    assert (rec["mesh"][0], rec["fem"][0], rec["rom"][0]) == ("reused", "computed", "computed")
    assert "material" in rec["fem"][1]
    # what the runner would do next: every later output is out of date through the new ROM
    for step in plan(load_scene(scene, sets), out, ("hbm", "ti", "validation")):
        assert step.todo == step.outputs and "rom.h5" in step.why, (step.stage.name, step.why)
    assert all(a == "reused" for a, _ in _records_with(scene, out, sets, until="rom").values())
    # same mesh and density, stiffer material: every frequency scales with sqrt(E)
    with h5py.File(base / "fem.h5") as a, h5py.File(out / "fem.h5") as b:
        ratio = b["frequencies"][:6] / a["frequencies"][:6]
    np.testing.assert_allclose(ratio, np.sqrt(110e9 / 108e9), rtol=1e-8)


def _records_with(scene_path, out, overrides, **kw):
    progress = Progress(quiet=True)
    run_scene(load_scene(scene_path, overrides), out, progress=progress, **kw)
    return {r.stage: (r.action, r.why) for r in progress.records}


@pytest.mark.parametrize("item, message", [
    ("contact.muu=0.1", "unknown key 'muu' in [contact] (did you mean 'mu'?)"),
    ("material.E=stiff", "[material] E must be a number, got 'stiff'"),
    ("material.nu=0.5", "Poisson's ratio nu must lie in"),
    ("contakt.mu=0.1", "unknown section [contakt] (did you mean 'contact'?)"),
    ("mu=0.1", "expected SECTION.KEY=VALUE"),
])
def test_a_bad_override_is_refused_and_nothing_is_written(tiny, tmp_path, capsys, item, message):
    scene, out = tiny
    before = {p: p.stat().st_mtime_ns for p in out.rglob("*")}
    fresh = tmp_path / "never"
    for d in (out, fresh):
        assert main(["run", str(scene), "--out", str(d), "--set", item]) == 2
        assert message in capsys.readouterr().err
    assert not fresh.exists()
    assert before == {p: p.stat().st_mtime_ns for p in out.rglob("*")}


def test_show_prints_a_scene_that_parses_back_to_the_same(tiny, capsys):
    from pipelines.scene import SECTIONS

    scene, _ = tiny
    sets = ["contact.mu=0.2", "hbm.start=omega_min", "blade.rotation=-", 'hbm.methods=["rl"]']
    assert main(["show", str(scene), *sum((["--set", s] for s in sets), [])]) == 0
    text = capsys.readouterr().out
    shown, expected = parse_scene(text, scene), load_scene(scene, sets)
    for section in SECTIONS:
        assert getattr(shown, section) == getattr(expected, section), section
    assert (shown.contact.mu, shown.hbm.start, shown.blade.rotation, shown.hbm.methods) == \
        (0.2, "omega_min", "-", ("rl",))
    assert "max_points = 4000" in text and 'ordering = "pord"' in text  # defaults written out


# -- ParaView files ----------------------------------------------------------------------------

def test_paraview_files_hold_the_modes_and_the_nfrc_point(tiny):
    import xml.etree.ElementTree as ET

    import meshio

    from pipelines.branch_store import load_branch
    from pipelines.stages.hbm import chosen_point
    from pipelines.vtu import mode_name

    _, out = tiny
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
    # the HBM instants: at the contact nodes the recovered full field is the NFRC's own
    # boundary solution (its stored harmonics, synthesised here) in each node's frame
    stored = load_branch(out / "nfrc_dlft.h5")
    i = chosen_point(stored, None)
    omega, xb = stored.branch.omega[i], stored.extras["harmonics"][i]  # (2 N_h + 1, 27), m
    entries = ET.parse(out / "figures" / "hbm_dlft.pvd").getroot().findall("./Collection/DataSet")
    assert len(entries) == 16 and len(list((out / "figures" / "hbm_dlft").glob("*.vtu"))) == 16
    k = np.arange(1, (xb.shape[0] - 1) // 2 + 1)
    for e in entries:
        vtu = meshio.read(out / "figures" / e.get("file"))
        np.testing.assert_array_equal(vtu.points, nodes)
        tau = omega * float(e.get("timestep"))
        local = xb[0] + np.cos(k * tau) @ xb[1::2] + np.sin(k * tau) @ xb[2::2]  # (27,) r, theta, z per node
        expected = np.einsum("jlx,jl->jx", frames, local.reshape(-1, 3))  # global x, y, z
        # the recovery matrix and the file hold float32 (relative round-off 6e-8; at a contact
        # node the recovery is the node's frame, the fixed-interface modes vanish there): 1e-6
        np.testing.assert_allclose(vtu.point_data["displacement"][bnodes], expected, rtol=0,
                                   atol=1e-6 * abs(expected).max())


def test_nfrc_files_carry_the_dynamical_content_of_every_point(tiny):
    """Eqs. (32)-(34) per point: harmonic contributions are the |c_k| of the stored LE radial
    harmonics, modal contributions of the ROM's modes sum to 1 and the file names the modes'
    frequencies, which are the ROM's."""
    from pipelines.branch_store import load_branch

    _, out = tiny
    stored = load_branch(out / "nfrc_rl.h5")
    le = stored.extras["harmonics"][:, :, 0]  # (m, 2 N_h + 1), m
    ref = np.concatenate([np.abs(le[:, :1]), np.hypot(le[:, 1::2], le[:, 2::2])], axis=1)
    np.testing.assert_allclose(stored.extras["harmonic_contribution"], ref, rtol=1e-12, atol=1e-18)
    mc = stored.extras["modal_contribution"]
    np.testing.assert_allclose(mc[stored.branch.converged].sum(axis=1), 1.0, rtol=1e-12)
    with h5py.File(out / "nfrc_rl.h5") as h5, h5py.File(out / "rom.h5") as rom:
        f = h5["modes/frequencies"][()]
        assert h5["modes/frequencies"].attrs["unit"] == "rad/s"
        np.testing.assert_allclose(f[:6], np.sort(rom["frequencies"][()])[:6], rtol=1e-6)
    # a two-lobe casing repeats every half revolution: the primary branch (omega = 2 Omega)
    # has no odd harmonic; between 1900 and 2000 rad/s (2B / 4 = 1946 rad/s) it is 1B and 2B
    h = stored.extras["harmonic_contribution"]
    assert h[:, 1::2].max() < 1e-6 * h.max()  # to the Newton tolerance
    assert np.all(mc[:, :2].sum(axis=1) > 0.85)


def _fake_artifact(folder, scene, stage, file, recorded_text):
    """An artifact of `stage` as `scene` would make it (its inputs, no data), recording
    `recorded_text` as its scene; returns (path)."""
    import json

    from pipelines.runner import expected_inputs

    comp, h = expected_inputs(scene, (stage,))[file]
    path = folder / file
    with h5py.File(path, "w") as h5:
        h5.attrs["scene"] = recorded_text
        h5.attrs["inputs_hash"] = h
        h5.attrs["inputs"] = json.dumps(comp, sort_keys=True)
    return path


def _reason(path, scene, stage):
    from pipelines.runner import expected_inputs, why_stale

    comp, h = expected_inputs(scene, (stage,))[path.name]
    return why_stale(path, comp, h, verify=False, scene=scene)


def test_a_reason_never_quotes_an_old_value_that_a_changed_default_made_up(tmp_path):
    """An artifact made when n_time, unset in the scene file, defaulted to 1000: its
    recorded text read with today's default (1024) is not the scene it was made with, so the
    reason cannot quote the old value; it names what the stage reads. Where the recorded text
    does give the recorded hash, the key and its two values are named."""
    base = Path(__file__).resolve().parents[2] / "scenes" / "rotor67_coarse.toml"
    text = base.read_text().replace("n_time = 1024\n", "")
    assert "n_time" not in text
    made = parse_scene(text, base, ["hbm.n_time=1000"])  # what was hashed then
    path = _fake_artifact(tmp_path, made, "hbm", "nfrc_dlft.h5", text)
    now = parse_scene(text.replace("[hbm]\n", "[hbm]\nn_time = 2048\n"), base)
    assert _reason(path, now, "hbm") == "inputs changed: hbm except methods"  # not "1024 -> 2048"
    path = _fake_artifact(tmp_path, parse_scene(text, base), "hbm", "nfrc_dlft.h5", text)
    assert _reason(path, now, "hbm") == "inputs changed: hbm.n_time 1024 -> 2048"


def test_a_long_list_that_changed_names_its_first_changed_item(tmp_path):
    """Lists cut to 40 characters can read the same on both sides: the first item that
    differs is named, or the lengths."""
    base = Path(__file__).resolve().parents[2] / "scenes" / "rotor67_coarse.toml"
    text = base.read_text()
    old = parse_scene(text, base, ["isolas.harmonics=[1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14]"])
    path = _fake_artifact(tmp_path, old, "isolas", "isolas.h5", old.text)
    new = parse_scene(text, base, ["isolas.harmonics=[1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 15]"])
    assert _reason(path, new, "isolas") == "inputs changed: isolas.harmonics[13] 14 -> 15"
    new = parse_scene(text, base, ["isolas.harmonics=[1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15]"])
    assert _reason(path, new, "isolas") == "inputs changed: isolas.harmonics (14 -> 15 items)"


def test_a_changed_input_file_is_named_as_a_file():
    """The user's mesh file and the [mesh] section are told apart."""
    from pipelines.runner import _component_name

    assert _component_name("file mesh") == "mesh file"
    assert _component_name("scene mesh") == "mesh"
    assert _component_name("scene hbm~methods") == "hbm except methods"
    assert _component_name("upstream rom.h5") == "rom.h5"


@pytest.mark.parametrize("stage, file, override", [
    ("fem", "fem.h5", 'material.name="Ti-6246"'),  # a label: no number of the FEM reads it
    ("isolas", "isolas.h5", "isolas.workers=1"),  # the search's result does not depend on it
    # how the FEM is computed, not what (runner.HOW_NOT_WHAT: the same modes to 1.1e-10)
    ("fem", "fem.h5", 'fem.solver="mumps"'),
    ("fem", "fem.h5", 'fem.ordering="amd"'),
    ("fem", "fem.h5", "fem.out_of_core=true"),
])
def test_settings_no_result_reads_leave_the_artifact_current(tmp_path, stage, file, override):
    base = Path(__file__).resolve().parents[2] / "scenes" / "rotor67_coarse.toml"
    made = parse_scene(base.read_text(), base)
    path = _fake_artifact(tmp_path, made, stage, file, made.text)
    assert _reason(path, parse_scene(base.read_text(), base, [override]), stage) is None


def test_fem_h5_follows_the_count_of_fixed_interface_modes_it_computes(tmp_path):
    """The fem stage computes max([fem] n_fixed_interface_modes, [rom] n_fixed_modes) modes:
    fewer ROM modes, or more up to the fem key, leave fem.h5 current; more than it computed
    make it stale, and the reason gives both counts."""
    base = Path(__file__).resolve().parents[2] / "scenes" / "rotor67_coarse.toml"
    made = parse_scene(base.read_text(), base, ["rom.n_fixed_modes=8"])
    assert made.fixed_interface_modes == 12  # [fem] n_fixed_interface_modes's default
    path = _fake_artifact(tmp_path, made, "fem", "fem.h5", made.text)
    for n in (4, 12):
        assert _reason(path, parse_scene(base.read_text(), base, [f"rom.n_fixed_modes={n}"]), "fem") is None
    more = parse_scene(base.read_text(), base, ["rom.n_fixed_modes=14"])
    assert _reason(path, more, "fem") == "inputs changed: fixed_interface_modes 12 -> 14"
    assert _reason(path, parse_scene(base.read_text(), base, ["fem.n_fixed_interface_modes=14"]),
                   "fem") == "inputs changed: fixed_interface_modes 12 -> 14"


def test_a_blade_source_of_another_kind_names_the_files_not_the_keys_now_read(tmp_path):
    """mesh.h5 meshed from a table, then the scene gives a mesh file: the two files and the
    changed unit are named; [blade] axis, root and contact_nodes, read for a mesh file only,
    are named only where they differ from the recorded scene's."""
    base = Path(__file__).resolve().parents[2] / "scenes" / "rotor67_coarse.toml"
    table = parse_scene(base.read_text(), base)
    path = _fake_artifact(tmp_path, table, "mesh", "mesh.h5", table.text)
    (tmp_path / "blade.inp").write_text("*NODE\n1, 0, 0, 0\n")
    lines = [line for line in base.read_text().splitlines()
             if not line.startswith(("geometry", "format", "units", "hub_section", "tip_section"))]
    text = "\n".join(lines).replace("[blade]", f'[blade]\nmesh = "{tmp_path / "blade.inp"}"\nunits = "m"')
    assert _reason(path, parse_scene(text, base), "mesh") == \
        'inputs changed: geometry file (gone), mesh file (new), blade.units "ft" -> "m"'
    assert _reason(path, parse_scene(text, base, ["blade.axis=x"]), "mesh") == \
        'inputs changed: geometry file (gone), mesh file (new), blade.axis, blade.units "ft" -> "m"'


def test_an_artifact_made_when_the_stage_read_other_keys_says_so(tmp_path):
    """fem.h5 recorded with the keys an earlier version read ([fem] whole, [rom]
    n_fixed_modes): unchanged values give no list of keys, a changed one is named."""
    import json

    base = Path(__file__).resolve().parents[2] / "scenes" / "rotor67_coarse.toml"
    made = parse_scene(base.read_text(), base)
    path = _fake_artifact(tmp_path, made, "fem", "fem.h5", made.text)
    with h5py.File(path, "r+") as h5:
        comp = json.loads(h5.attrs["inputs"])
        for key in ("fem~n_fixed_interface_modes", "fixed_interface_modes"):
            del comp[f"scene {key}"]
        for key in ("fem", "rom.n_fixed_modes"):
            comp[f"scene {key}"] = made.key_hash(key)
        h5.attrs["inputs"] = json.dumps(comp, sort_keys=True)
        h5.attrs["inputs_hash"] = "an earlier version's"
    assert _reason(path, made, "fem") == "made by an earlier version, which read other scene keys"
    assert _reason(path, parse_scene(base.read_text(), base, ["fem.tol=1e-9"]), "fem") == \
        "inputs changed: fem except n_fixed_interface_modes"


def test_an_imported_mesh_follows_n_boundary_and_its_include_files(tmp_path):
    """A deck whose nodes sit in an *INCLUDE file, imported without listed contact nodes:
    [mesh] n_boundary places them, so changing it makes mesh.h5 stale; so does an edit of
    the included file (its content is hashed like the deck's). With the contact nodes listed,
    n_boundary is not read and leaves mesh.h5 current."""
    base = Path(__file__).resolve().parents[2] / "scenes" / "rotor67_coarse.toml"
    (tmp_path / "blade.inp").write_text("*INCLUDE, INPUT=nodes.inp\n*ELEMENT, TYPE=C3D10\n")
    (tmp_path / "nodes.inp").write_text("*NODE\n1, 0, 0, 0\n")
    lines = [line for line in base.read_text().splitlines()
             if not line.startswith(("geometry", "format", "units", "hub_section", "tip_section"))]
    text = "\n".join(lines).replace("[blade]", f'[blade]\nmesh = "{tmp_path / "blade.inp"}"\nunits = "m"')
    made = parse_scene(text, base)
    path = _fake_artifact(tmp_path, made, "mesh", "mesh.h5", made.text)
    assert _reason(path, parse_scene(text, base), "mesh") is None
    assert _reason(path, parse_scene(text, base, ["mesh.n_boundary=5"]), "mesh") == \
        "inputs changed: mesh.n_boundary 9 -> 5"
    (tmp_path / "nodes.inp").write_text("*NODE\n1, 0, 0, 0.001\n")
    assert _reason(path, parse_scene(text, base), "mesh") == "inputs changed: mesh include 1 file"
    listed = text.replace('units = "m"', 'units = "m"\ncontact_nodes = [1, 2]')
    made = parse_scene(listed, base)
    path = _fake_artifact(tmp_path, made, "mesh", "mesh.h5", made.text)
    assert _reason(path, parse_scene(listed, base, ["mesh.n_boundary=5"]), "mesh") is None


def test_each_reason_to_recompute_an_artifact_is_its_own(tmp_path):
    """why_stale's reasons where the file cannot be read as made from these inputs, and the
    list of changed keys: an unset value is called so, five changed keys name three and
    count the rest."""
    base = Path(__file__).resolve().parents[2] / "scenes" / "rotor67_coarse.toml"
    made = parse_scene(base.read_text(), base)
    path = _fake_artifact(tmp_path, made, "isolas", "isolas.h5", made.text)
    assert _reason(path, made, "isolas") is None
    assert _reason(path, parse_scene(base.read_text(), base, ["isolas.omega_min=500"]), "isolas") == \
        "inputs changed: isolas.omega_min unset -> 500"
    five = ["isolas.omega_min=500", "isolas.omega_max=1900", "isolas.n_omega=11", "isolas.n_modes=3",
            "isolas.tolerance=0.02"]
    got = _reason(path, parse_scene(base.read_text(), base, five), "isolas")
    assert got.startswith("inputs changed: isolas.") and got.endswith(", 2 more") and got.count(" -> ") == 3, got
    with h5py.File(path, "r+") as h5:
        h5.attrs["inputs"] = "{not json"
    assert _reason(path, parse_scene(base.read_text(), base, five), "isolas") == "made from other inputs"
    link = tmp_path / "link.h5"
    link.symlink_to(tmp_path / "gone.h5")
    from pipelines.runner import expected_inputs, why_stale

    comp, h = expected_inputs(made, ("isolas",))["isolas.h5"]
    assert why_stale(link, comp, h, verify=False, scene=made) == "broken link"


def test_a_stage_reused_from_another_code_version_says_which_and_how_to_recompute(tiny, tmp_path, capsys,
                                                                                 monkeypatch):
    scene, base = tiny
    out = fresh_copy(base, tmp_path / "out")
    made_by = art.read_attrs(out / "rom.h5")["code_version"]
    capsys.readouterr()
    assert main(["run", str(scene), "--out", str(out), "--until", "rom"]) == 0
    printed = capsys.readouterr().out
    assert "[rom] up to date (rom.h5)\n" in printed and "made by bladerub" not in printed, printed
    # the same files, read by an upgraded code: still current (by their inputs), and the log says by whom
    monkeypatch.setattr(art, "code_version", lambda: "9.9.9+upgraded")
    before = (out / "rom.h5").read_bytes()
    assert main(["run", str(scene), "--out", str(out), "--until", "rom"]) == 0
    printed = capsys.readouterr().out
    # the advice once, on the first stage; the later ones of that version name it only
    assert (f"[mesh] up to date (mesh.h5); made by bladerub {made_by}, not this 9.9.9+upgraded: delete the file "
            "or pass --force to recompute with this version") in printed, printed
    assert f"[fem] up to date (fem.h5); made by bladerub {made_by} too\n" in printed, printed
    assert f"[rom] up to date (rom.h5); made by bladerub {made_by} too\n" in printed, printed
    assert printed.count("--force") == 1, printed
    assert (out / "rom.h5").read_bytes() == before
    # a stage of another version than those named gets the advice again
    (out / "rom.h5").unlink()
    monkeypatch.setattr(art, "code_version", lambda: "0.0.1+older")
    assert main(["run", str(scene), "--out", str(out), "--until", "rom", "--quiet"]) == 0
    monkeypatch.setattr(art, "code_version", lambda: "9.9.9+upgraded")
    capsys.readouterr()
    assert main(["run", str(scene), "--out", str(out), "--until", "rom"]) == 0
    printed = capsys.readouterr().out
    assert ("[rom] up to date (rom.h5); made by bladerub 0.0.1+older, not this 9.9.9+upgraded: delete the file "
            "or pass --force to recompute with this version") in printed, printed


def _running_because(printed: str, stage: str) -> str:
    """The reason the log gives for running `stage` ("" when it did not run)."""
    head = f"[{stage}] running ("
    return printed.split(head)[1].split("\n")[0] if head in printed else ""


def test_friction_set_on_the_command_line_reruns_what_reads_it_and_a_dry_run_says_so_first(tiny, tmp_path, capsys):
    # another friction set on the command line reruns both treatments, the sweep, the search
    # and the validation and reuses the mesh, FEM and ROM; with the DLFT NFRC of it finished
    # and then left as an interrupted run's partial file, the dry run must name the stages,
    # the resume and the figures that the real run then computes, resumes and draws, and
    # touch nothing (not even the lock). One run of each, the stages' work being most of
    # the time.
    scene, base = tiny
    out = fresh_copy(base, tmp_path / "out")
    made = {p.name: p.read_bytes() for p in out.glob("*.h5")}
    sets = ["--set", "contact.mu=0.1"]
    capsys.readouterr()
    assert main(["run", str(scene), "--out", str(out), "--until", "hbm", *sets]) == 0
    printed = capsys.readouterr().out
    for s in ("mesh", "fem", "rom"):
        assert f"[{s}] up to date" in printed, printed
    assert "contact" in _running_because(printed, "hbm"), printed
    (out / "nfrc_dlft.h5").rename(out / "nfrc_dlft.partial.h5")
    with h5py.File(out / "nfrc_dlft.partial.h5", "a") as h5:  # started by another run than the figures' NFRC
        h5.attrs["created"] = "2026-01-01T00:00:00+00:00"
    n = int(art.read_attrs(out / "nfrc_dlft.partial.h5")["n_points"])
    assert n > 1

    def state():
        return {p: (p.stat().st_mtime_ns, p.stat().st_size) for p in out.rglob("*")}

    before = state()
    capsys.readouterr()
    assert main(["run", str(scene), "--out", str(out), "--dry-run", *sets]) == 0
    said = capsys.readouterr().out.splitlines()
    assert state() == before
    assert said[:3] == [f"[{s}] up to date ({s}.h5)" for s in ("mesh", "fem", "rom")], said
    assert (f"[hbm] would compute nfrc_dlft.h5 (nfrc_dlft.h5: no artifact), resuming from {n} points of nfrc_dlft.partial.h5"
            in said), said[3]
    assert any(line.startswith("  estimate: 1 NFRC(s) of ") for line in said), said
    # of another friction, the same partial file is one a run starts over from
    assert main(["run", str(scene), "--out", str(out), "--dry-run", "--set", "contact.mu=0.11"]) == 0
    other = capsys.readouterr().out.splitlines()
    assert other[3] == ("[hbm] would compute nfrc_dlft.h5, nfrc_rl.h5 (nfrc_dlft.h5: no artifact; nfrc_rl.h5: inputs "
                        "changed: contact.mu 0.1 -> 0.11), starting over from nfrc_dlft.partial.h5 (other inputs, "
                        "or unreadable)"), other[3]
    would = {re.match(r"\[(\w+)\] would compute ", line).group(1) for line in said if " would compute " in line}
    figures = [line for line in said if line.startswith("[figures] would draw: ")]
    assert len(figures) == 1, said
    drawn_said = set(re.findall(r"(\w+) \(after ", figures[0]))
    assert main(["run", str(scene), "--out", str(out), *sets]) == 0
    printed = capsys.readouterr().out
    assert set(re.findall(r"\[(\w+)\] running \(", printed)) == would == {"hbm", "ti", "isolas", "validation"}
    for s in ("ti", "isolas", "validation"):  # isolas, validation: the whole [contact] section
        assert "contact" in _running_because(printed, s), (s, printed)
    assert f"dlft: resuming from {n} points on disk" in printed
    remade = {p.name: p.read_bytes() for p in out.glob("*.h5")}
    assert {k for k in made if made[k] != remade[k]} == {"nfrc_dlft.h5", "nfrc_rl.h5", "ti.h5", "isolas.h5",
                                                         "validation.h5"}
    # the artifacts made by this run carry the resolved scene with the override
    text = art.read_attrs(out / "nfrc_dlft.h5")["scene"]
    assert "--set contact.mu=0.1" in text and parse_scene(text).contact.mu == 0.1
    assert "--set" not in art.read_attrs(out / "rom.h5")["scene"]  # reused, not rewritten
    drawn = re.search(r"\[figures\] drawn: (.*) -> ", printed).group(1).split(", ")
    assert set(drawn) == drawn_said, (drawn, figures)
    # and now nothing is left to do
    assert main(["run", str(scene), "--out", str(out), "--dry-run", *sets]) == 0
    said = capsys.readouterr().out.splitlines()
    assert not any(" would " in line for line in said) and said[-1] == "[figures] up to date", said
    # a run the size guard would refuse: the dry run says so, with the refusal the run then meets
    small = [*sets, "--set", "hbm.n_harmonics=6", "--set", "limits.memory_gb=0.01"]
    assert main(["run", str(scene), "--out", str(out), "--dry-run", *small]) == 0
    refused = [line for line in capsys.readouterr().out.splitlines() if line.startswith("a run would be refused: ")]
    assert len(refused) == 1 and "[hbm] " in refused[0], refused
    assert main(["run", str(scene), "--out", str(out), "--quiet", *small]) == 2
    assert capsys.readouterr().err.strip().endswith(refused[0][len("a run would be refused: "):])
    # while a run holds the folder, the dry run names it first (read from the kernel's lock
    # table: trying the lock would refuse, for an instant, a run starting then)
    from pipelines import folder

    with folder.hold(out, "bladerub run the-other-one"):
        assert main(["run", str(scene), "--out", str(out), "--dry-run", *sets]) == 0
        said = capsys.readouterr().out.splitlines()
        with pytest.raises(folder.FolderBusy):  # and the lock is still held, by that run alone
            with folder.hold(out, "a third"):
                pass
    assert said[0].startswith(f"a run holds this folder: pid {os.getpid()} on ") and "the-other-one" in said[0], said
    assert main(["run", str(scene), "--out", str(out), "--dry-run", *sets]) == 0
    assert not capsys.readouterr().out.startswith("a run holds")


def test_the_friction_lock_warning_is_said_once_a_run_by_the_first_stage_that_computes(tiny, tmp_path, capsys):
    # mu = 0.15 drags the coarse ROM's node 6 into the casing: the rom, hbm and ti stages each
    # used to print the warning; a run says it once, and a stage after a reused ROM says it
    scene, base = tiny
    out = fresh_copy(base, tmp_path / "out")
    for name in ("rom.h5", "nfrc_dlft.h5", "nfrc_rl.h5", "ti.h5"):
        (out / name).unlink()
    capsys.readouterr()
    assert main(["run", str(scene), "--out", str(out), "--until", "ti"]) == 0
    printed = capsys.readouterr().out
    said = [line for line in printed.splitlines() if "WARNING: friction mu = 0.15 drags contact node(s) 6" in line]
    assert len(said) == 1 and printed.index(said[0]) < printed.index("[rom] done"), said
    assert "[hbm] running" in printed and "[ti] " in printed
    assert main(["run", str(scene), "--out", str(out), "--until", "ti", "--set", "contact.mu=0.149"]) == 0
    printed = capsys.readouterr().out
    said = [line for line in printed.splitlines() if "WARNING: friction mu = 0.149 drags contact node(s) 6" in line]
    assert "[rom] up to date" in printed and len(said) == 1, printed
