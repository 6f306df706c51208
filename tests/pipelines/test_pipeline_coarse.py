"""End to end on the coarse rotor 67 scene: mesh -> fem -> rom through the CLI.

Checks what only the whole chain shows: artifacts exist with provenance, a second run
skips up-to-date stages, a changed input recomputes only what depends on it, bad input
stops with a clear error without touching good artifacts, and the ROM built from the
files agrees with the full model it came from.
"""

import shutil

import numpy as np
import pytest

from pipelines import artifacts as art
from pipelines.cli import main
from rom.model import RomModel
from support import SHARED, distance_to_polyline, fresh_copy



def test_artifacts_have_provenance(coarse_run):
    scene, out = coarse_run
    for name in ("mesh.h5", "fem.h5", "rom.h5"):
        attrs = art.read_attrs(out / name)
        assert attrs["stage"] == name[:-3]
        assert attrs["scene"] == scene.read_text()
        assert len(attrs["inputs_hash"]) == 64 and attrs["code_version"] and attrs["units"].startswith("{")
    assert not list(out.glob(".*tmp*")), "temporary files left behind"


def test_rom_agrees_with_full_model(coarse_run):
    _, out = coarse_run
    rom = art.read_artifact(out / "rom.h5", RomModel)
    assert rom.K.shape == (39, 39) and rom.n_boundary == 9
    assert np.allclose(rom.K, rom.K.T, rtol=0, atol=1e-12 * abs(rom.K).max())
    assert np.linalg.eigvalsh(rom.M).min() > 0 and np.linalg.eigvalsh(rom.K).min() > 0
    w, wf = rom.frequencies[:6], rom.full_frequencies[:6]
    # Ritz bound (the ROM is a Rayleigh-Ritz projection of the full model): never below it,
    # beyond the eigen-solver's relative tolerance.
    assert np.all(w >= wf * (1 - 1e-8))
    # 1B, 2B, 1T within 0.5 % even on the coarse mesh (the default scene's six are in the README)
    assert np.all((w[:3] - wf[:3]) / wf[:3] < 5e-3)
    # the LE node is first, theta relative to it, rho ~ the rotor 67 tip radius (0.24-0.26 m)
    assert rom.theta[0] == 0.0 and np.all((rom.rho > 0.2) & (rom.rho < 0.27))


def test_mode_pngs_are_rendered(coarse_run):
    _, out = coarse_run
    from PIL import Image

    pngs = sorted((out / "figures").glob("mode_*.png"))
    assert [p.name for p in pngs] == ["mode_01.png", "mode_02.png"]
    img = np.asarray(Image.open(pngs[0]).convert("L"), dtype=float)
    assert img.shape == (900, 1200) and img.std() > 10  # not blank


def test_second_run_skips_and_changes_recompute_downstream_only(coarse_run, tmp_path, capsys):
    scene, out = coarse_run[0], fresh_copy(coarse_run[1], tmp_path / "run")
    stamps = {n: (out / n).stat().st_mtime_ns for n in ("mesh.h5", "fem.h5", "rom.h5")}
    assert main(["run", str(scene), "--out", str(out), "--until", "rom"]) == 0
    assert "[mesh] up to date" in capsys.readouterr().out
    assert stamps == {n: (out / n).stat().st_mtime_ns for n in stamps}
    # a damping change touches the ROM only
    scene2 = tmp_path / "scene2.toml"
    scene2.write_text(scene.read_text().replace("damping_high = 5e-3", "damping_high = 6e-3"))
    assert main(["run", str(scene2), "--out", str(out), "--until", "rom"]) == 0
    printed = capsys.readouterr().out
    assert "[mesh] up to date" in printed and "[fem] up to date" in printed and "[rom] done" in printed
    rom = art.read_artifact(out / "rom.h5", RomModel)
    assert rom.damping_ratios.max() == pytest.approx(6e-3)


def test_bad_input_is_named_and_good_artifacts_survive(coarse_run, tmp_path, capsys):
    scene, out = coarse_run
    before = {n: (out / n).read_bytes() for n in ("mesh.h5", "rom.h5")}
    bad_geometry = tmp_path / "rotor67_truncated.dat"
    lines = (SHARED / "data/rotor67/rotor67geometry.dat").read_text().splitlines()
    bad_geometry.write_text("\n".join(lines[:600]) + "\n")  # cut inside surface 9
    bad = tmp_path / "bad.toml"
    text = scene.read_text()
    start = text.index("geometry = ")
    end = text.index("\n", start)
    bad.write_text(text[:start] + f'geometry = "{bad_geometry}"' + text[end:])
    assert main(["run", str(bad), "--out", str(out), "--until", "rom"]) == 2
    assert "surface(s) 10, 11, 12, 13, 14 missing" in capsys.readouterr().err
    # a misspelt key and nu >= 0.5 are refused before anything runs
    typo = tmp_path / "typo.toml"
    typo.write_text(text.replace("[material]", "[material]\nyoungs = 1e9"))
    assert main(["run", str(typo), "--out", str(out)]) == 2
    assert "unknown key 'youngs' in [material]" in capsys.readouterr().err
    nu = tmp_path / "nu.toml"
    nu.write_text(text.replace("nu = 0.34", "nu = 0.5"))
    assert main(["run", str(nu), "--out", str(out)]) == 2
    assert "nu must lie in" in capsys.readouterr().err
    assert before == {n: (out / n).read_bytes() for n in before}


def _hbm_scene(scene, out, name):
    """The coarse scene with a short, cheap NFRC (N_h = 5, N_t = 64, Omega in [1900, 2000])."""
    text = scene.read_text()
    start = text.index("[hbm]")
    end = text.index("[ti]")
    hbm = ('[hbm]\nmethods = ["dlft"]\nn_harmonics = 5\nn_time = 64\nomega_min = 1900.0\n'
           'omega_max = 2000.0\n\n')
    path = out / name
    path.write_text(text[:start] + hbm + text[end:])
    return path


def test_hbm_stage_writes_points_as_it_goes_and_resumes(coarse_run, tmp_path, monkeypatch, capsys):
    from pipelines import branch_store

    scene, out = coarse_run
    # output folders sharing the ROM: one run straight through, one interrupted then resumed,
    # one given the interrupted run's partial file under other inputs
    runs = {}
    for label in ("straight", "interrupted", "other"):
        d = tmp_path / label
        d.mkdir()
        for name in ("mesh.h5", "fem.h5", "rom.h5"):
            (d / name).symlink_to(out / name)
        runs[label] = _hbm_scene(scene, d, "hbm.toml")
    assert main(["run", str(runs["straight"]), "--out", str(runs["straight"].parent), "--until", "hbm"]) == 0
    ref = branch_store.load_branch(runs["straight"].parent / "nfrc_dlft.h5")
    assert ref.complete and ref.attrs["status"] == "reached omega_min" and len(ref.branch) > 6
    assert (runs["straight"].parent / "figures" / "nfrc.png").is_file()

    real_append = branch_store.BranchStore.append

    class Interrupt(Exception):
        pass

    def append_then_die(self, point, extras=None):
        if self.n_points == 5:
            raise Interrupt()
        real_append(self, point, extras)

    monkeypatch.setattr(branch_store.BranchStore, "append", append_then_die)
    d = runs["interrupted"].parent
    with pytest.raises(Interrupt):
        main(["run", str(runs["interrupted"]), "--out", str(d), "--until", "hbm"])
    assert not (d / "nfrc_dlft.h5").exists()  # never taken as a complete result ...
    partial = branch_store.load_branch(d / "nfrc_dlft.partial.h5", allow_partial=True)
    assert len(partial.branch) == 5  # ... but every point computed so far is on disk
    monkeypatch.setattr(branch_store.BranchStore, "append", real_append)
    # the same partial file under other inputs (another mu) is not resumed from: it starts over
    other = runs["other"].parent
    shutil.copy2(d / "nfrc_dlft.partial.h5", other / "nfrc_dlft.partial.h5")
    capsys.readouterr()
    assert main(["run", str(runs["other"]), "--out", str(other), "--until", "hbm",
                 "--set", "contact.mu=0.1"]) == 0
    assert "resuming" not in capsys.readouterr().out
    fresh = branch_store.load_branch(other / "nfrc_dlft.h5")
    # its first point is mu = 0.1's: 0.30 of the partial file's largest unknown away (measured)
    moved = np.abs(fresh.branch.x[0] - partial.branch.x[0]).max()
    assert fresh.complete and moved > 0.03 * np.abs(partial.branch.x[0]).max()
    assert main(["run", str(runs["interrupted"]), "--out", str(d), "--until", "hbm"]) == 0
    resumed = branch_store.load_branch(d / "nfrc_dlft.h5")
    assert resumed.complete and resumed.attrs["status"] == ref.attrs["status"]
    # The 5 points on disk are kept as they were; the rest follow the same branch. Not at the
    # same arc-length positions: the GMRES solver's reused preconditioner (not stored) makes
    # the Newton iterates, hence the step sequence, differ at the solver's tolerance. So:
    # every resumed point on the uninterrupted run's polyline in the continuation's metric
    # (u, omega / 100 rad/s), to the sag of its chords: at ds_max = 5 a resumed point halfway
    # between two of the other run's sits ~0.07 step off the chord (measured); a point on
    # another sheet would be a step or more away.
    np.testing.assert_array_equal(resumed.branch.omega[:5], partial.branch.omega)
    pa = np.column_stack([ref.branch.x, ref.branch.omega / 100.0])
    pb = np.column_stack([resumed.branch.x, resumed.branch.omega / 100.0])
    dist = distance_to_polyline(pb, pa)
    step = np.median(np.linalg.norm(np.diff(pa, axis=0), axis=1))
    assert abs(len(pb) - len(pa)) <= 0.1 * len(pa)
    assert dist.max() < 0.2 * step
    assert abs(resumed.branch.omega[-1] - ref.branch.omega[-1]) < 1e-9  # both end on the bound
