"""Rotor 37 end to end on its coarse scene: mesh -> FEM -> ROM through the CLI, the ROM
checked against its full model as rotor 67's is, and its NFRC over the primary resonance of
its three-lobe casing (a short range at low N_h: the whole NFRC is README material)."""
import dataclasses
from pathlib import Path

import numpy as np
import pytest

from pipelines import artifacts as art
from pipelines.cli import main
from pipelines.scene import load_scene
from rom.model import RomModel
from support import SHARED

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def rotor37(tmp_path_factory):
    out = tmp_path_factory.mktemp("rotor37")
    scene = out / "scene.toml"
    text = (ROOT / "scenes" / "rotor37_coarse.toml").read_text().replace("../../shared", str(SHARED))
    scene.write_text(text.replace("n_modes = 6", "n_modes = 0"))  # no pictures needed here
    assert main(["run", str(scene), "--out", str(out), "--until", "rom", "--quiet"]) == 0
    return load_scene(scene), art.read_artifact(out / "rom.h5", RomModel)


def test_rom_agrees_with_full_model(rotor37):
    _, rom = rotor37
    assert rom.K.shape == (39, 39) and rom.n_boundary == 9
    for A in (rom.K, rom.M, rom.C):
        np.testing.assert_allclose(A, A.T, rtol=0, atol=1e-12 * abs(A).max())
    assert np.linalg.eigvalsh(rom.M).min() > 0 and np.linalg.eigvalsh(rom.K).min() > 0
    w, wf = rom.frequencies[:6], rom.full_frequencies[:6]
    # Ritz bound beyond the eigen-solver's tolerance, and 1B, 2B, 1T within 0.5 % (as rotor 67)
    assert np.all(w >= wf * (1 - 1e-8))
    assert np.all((w[:3] - wf[:3]) / wf[:3] < 5e-3)
    # the LE first; the contact nodes on the tip section (radius 25.2 cm at the LE, 24.4 cm at the TE)
    assert rom.theta[0] == 0.0 and np.all((rom.rho > 0.232) & (rom.rho < 0.254))
    # le-leads: the TE lies at +theta of the LE in the table, so the blade turns towards -theta
    assert rom.theta[-1] > 0.1 and rom.rotation == -1


@pytest.mark.parametrize("method", ["dlft", "rl"])
def test_nfrc_over_the_primary_resonance(rotor37, method):
    from hbm.harmonic.nfrc import compute_nfrc

    scene, rom = rotor37
    hbm = dataclasses.replace(scene.hbm, n_harmonics=8, n_time=66, omega_min=1700.0, omega_max=2200.0)  # N_t: 3 lobes
    r = compute_nfrc(rom, scene.casing, scene.contact, hbm, method)
    assert r.status == "reached omega_min" and r.converged.all()
    i = int(np.argmax(r.le_amplitude))
    # The three-lobe casing excites the 1B where 3 Omega = w_1B of the full model: the peak
    # sits there (measured -0.4 % DLFT, -1.9 % RL at N_h = 8; contact stiffening and the
    # friction move it by a few per cent at most), far above the amplitude of a tip that
    # just follows the casing, (c + p) / 2.
    assert r.omega[i] == pytest.approx(rom.full_frequencies[0] / 3, rel=0.03)
    half = 0.5 * (scene.casing.clearance + scene.casing.penetration)
    # Both contact laws give the same resonance: 0.845 (DLFT) and 0.936 mm (RL) measured at
    # N_h = 8, 0.866 and 0.865 mm at N_h = 40 (the README's NFRC): 0.84 to 1 mm here
    assert 0.80e-3 < r.le_amplitude[i] < 1.0e-3 and r.le_amplitude[i] > 3 * half
