"""Clones of the shared coarse runs (conftest.py) for tests that run or damage something."""
from __future__ import annotations

import shutil
from pathlib import Path

from support import coarse_text

ROOT = Path(__file__).resolve().parents[2]

#: [hbm], [ti], [isolas] and [validation] of a clone's scene: a short NFRC (~5 s per treatment),
#: a 4-speed sweep of 20 revolutions at dt = 4e-7 s (the coarse ROM's stability limit is 8.9e-7 s;
#: the validation stage's marches use the same dt, 20 periods each instead of the paper's 100,
#: and fewer Floquet analyses: dense QZ at this N_h, ~0.9 s each) and an isola search from 2
#: modal seeds and the sweep's periodic points; mesh, fem and rom do not depend on them.
SHORT = """[hbm]
methods = ["dlft", "rl"]
n_harmonics = 5
n_time = 64
omega_min = 1900.0
omega_max = 2000.0

[ti]
dt = 4e-7
n_revolutions = 20
n_keep = 2
omega_min = 1900.0
omega_max = 2000.0
n_omega = 4
samples_per_revolution = 64

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


def coarse_scene_text() -> str:
    """support.coarse_text() with the SHORT [hbm] and [ti]."""
    text = coarse_text()
    return text[: text.index("[hbm]")] + SHORT + text[text.index("[render]"):]


ARTIFACTS = ("mesh.h5", "fem.h5", "rom.h5", "nfrc_dlft.h5", "nfrc_rl.h5", "ti.h5", "isolas.h5", "validation.h5")


def clone(src: Path, dst: Path, copy=(), link=True) -> Path:
    """A folder `dst` holding src's figures (copied) and artifacts: symbolic links (read-only
    use: a run replaces a link, never writes through it), or copies for the names in `copy`
    (or all when link is False); and the scene of coarse_scene_text(). Returns dst/scene.toml."""
    dst.mkdir(parents=True, exist_ok=True)
    for name in ARTIFACTS:
        if (src / name).is_file():
            if name in copy or not link:
                shutil.copy2(src / name, dst / name)
            else:
                (dst / name).symlink_to((src / name).resolve())
    if (src / "figures").is_dir():
        shutil.copytree(src / "figures", dst / "figures")
    (dst / "scene.toml").write_text(coarse_scene_text())
    return dst / "scene.toml"
