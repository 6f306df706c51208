"""Fig. 9 (validation_METHOD.png, drawn by the validation stage's draw_time_signals) names the
friction lock, and a march repeated with a finer step, as the stage's log does.

A march that ends in permanent contact with mu at or above the ROM's contact-set limit
mu_set (rom.friction_lock) is the friction lock, a state of the model; below mu_set it is
permanent contact only. The log line says which (ti_verdict); the figure's row title must
say the same, not OrbitValidation.verdict() alone, which cannot tell them apart.
"""
import shutil
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from matplotlib.image import imread

from hbm.stability.selection import DoubledBranch
from hbm.ti.validation import OrbitValidation, departure
from pipelines import artifacts as art
from pipelines import figures
from pipelines.stages import validation as stage
from rom.model import load_rom

ROM = Path(__file__).resolve().parents[1] / "data" / "rotor67_coarse_rom.h5"  # mu_set = 0.1232


def _locked_march(n_b: int) -> OrbitValidation:
    """A march that left its orbit (deviation 5 amplitudes) with the LE in contact at every
    step of the last tenth (contact_fraction 1): outcome "permanent contact"."""
    n = 64
    tau = 2 * np.pi * np.arange(n) / n
    r = 1e-4 * np.cos(tau)[:, None] * np.ones(3)
    dev = np.full((20, 2), 5.0)
    growth, stays = departure(dev)
    frac = np.zeros(n_b)
    frac[0] = 1.0
    return OrbitValidation(omega=1000.0, subharmonic=1, n_periods=20, dt=1e-7, t0=0.0,
                           nodes=np.array([0, 1, n_b - 1]), tau=tau, distance=np.full((n, 3), 4e-4),
                           displacement=r, force=1e3 * np.abs(r), force_peak=np.ones(3), deviation=dev,
                           drift=np.full(2, 0.01), growth=growth, stays=stays, max_penetration=0.0,
                           contact_fraction=frac, outcome="permanent contact", repeat=1)


FIRST = "leaves (growth 3.1) with dt = 1e-07 s"


@pytest.mark.parametrize("mu, refined_from, words, nu", [
    (0.15, "", "TI leaves for permanent contact (LE): the friction lock, mu = 0.15 >= mu_set = 0.123)", 1),
    # an orbit of two revolutions (a period-doubled branch's): the title gives nu
    (0.1, "", "TI leaves for permanent contact (LE))", 2),
    # a march repeated with a finer step (the stage's dt_refinement): the figure says so as the log does
    (0.1, FIRST, f"TI leaves for permanent contact (LE); dt = 5e-08 s, the first march {FIRST})", 1),
])
def test_fig9_title_names_the_friction_lock_as_the_log_does(tmp_path, monkeypatch, mu, refined_from, words, nu):
    rom = load_rom(ROM)
    assert rom.friction_lock.mu_set == pytest.approx(0.1232, abs=1e-4)
    ti = _locked_march(rom.n_boundary)
    if refined_from:
        ti = replace(ti, dt=5e-8)
    assert ti.verdict() == "leaves for permanent contact (LE)"
    p = stage.ValidationPoint("primary", "dlft", True, "chosen", "nfrc_dlft.h5", 3, 1000.0, nu, np.zeros(4), 1e-3,
                              True, "analysed", 0, 0.97, ti, refined_from=refined_from)
    t = stage.TreatmentValidation("dlft", p, stage.ValidationPoint("isola", "dlft", False, "none"),
                                  stage.ValidationPoint("period_doubling", "dlft", False, "none"),
                                  DoubledBranch(False, "none"), 0.0)
    (tmp_path / "figures").mkdir()
    shutil.copy(ROM, tmp_path / "rom.h5")
    art.write_artifact(tmp_path / "validation.h5", stage.ValidationArtifact("absent", 1.5, 0.6, 0.0, dlft=t),
                       stage="validation")
    titles = {}
    save = figures._save

    def keep_titles(fig, path):
        titles[Path(path).name] = [ax.get_title().replace("\n", " ") for ax in fig.axes]
        return save(fig, path)

    monkeypatch.setattr(figures, "_save", keep_titles)
    stage.draw_time_signals(SimpleNamespace(out=tmp_path, scene=SimpleNamespace(contact=SimpleNamespace(mu=mu))))
    primary = titles["validation_dlft.png"][:2]  # the primary point's row: displacement and force
    assert primary == [f"primary, \u03a9 = 1000.0 rad/s{', ν = 2' if nu == 2 else ''} (stable, {words}"] * 2
    assert ("friction lock" in primary[0]) == (mu >= rom.friction_lock.mu_set)
    # the log line says the same
    log = stage._summary(t, rom, mu)[0]
    assert words.split(";")[0].rstrip(")").replace("TI leaves", "TI LEAVES") in log
    assert (f"dt = 5e-08 s, the first march {FIRST})" in log) == bool(refined_from)
    assert imread(tmp_path / "figures" / "validation_dlft.png")[..., :3].std() > 0.02
