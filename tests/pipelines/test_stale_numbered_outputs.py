"""Numbered outputs after a smaller count: a ParaView series written again with fewer
instants, or the mode pictures drawn again for fewer modes, leave no file of the longer one
(ParaView's file dialog groups numbered files into one series), only what the figure
declares (its files=, recorded in figures/manifest.json); a user's own files stay."""
from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import h5py
import numpy as np

from pipelines.progress import Progress
from pipelines.runner import MANIFEST, update_figures
from pipelines.scene import load_scene
from pipelines.stages.fem import MODES, mode_files
from pipelines.stages.hbm import _instants_files, _instants_stem
from pipelines.vtu import write_time_series
from test_render import bending_modes, plate_tet10

SCENE = Path(__file__).resolve().parents[2] / "scenes" / "rotor67_coarse.toml"


def _listing(folder: Path) -> set[str]:
    return {p.relative_to(folder).as_posix() for p in folder.rglob("*") if p.is_file()}


def test_a_shorter_hbm_series_leaves_only_its_own_snapshots(tmp_path):
    nodes, cells = plate_tet10(1, 1, 1)
    figures = tmp_path / "figures"
    for n in (5, 3):
        scene = load_scene(SCENE, [f"render.hbm_instants={n}"])
        stem = _instants_stem(scene)
        write_time_series(figures, stem, nodes, cells, np.arange(n) * 1e-3, np.zeros((n, len(nodes), 3)))
        if n == 5:  # a user's own files beside the series, names close to its pattern
            mine = {f"{stem}/{stem}_notes.vtu", f"{stem}/{stem}_0004.vtu", f"{stem}/{stem}_004.vtu.bak",
                    f"{stem}/other_004.vtu"}
            for name in mine:
                (figures / name).write_text("mine")
    assert _listing(figures) == set(_instants_files(scene)) | mine
    assert {f"{stem}/{stem}_{i:03d}.vtu" for i in range(3)} <= _listing(figures)
    assert (figures / f"{stem}.pvd").read_text().count("<DataSet ") == 3
    assert all((figures / name).read_text() == "mine" for name in mine)


def test_fewer_mode_pictures_leave_only_the_scene_modes_and_the_manifest_lists_them(tmp_path):
    nodes, cells = plate_tet10(4, 2, 1)
    modes = np.hstack([bending_modes(nodes)] * 2)  # (3n, 4)
    with h5py.File(tmp_path / "mesh.h5", "w") as h5:
        h5["nodes"], h5["cells"] = nodes, cells
    with h5py.File(tmp_path / "fem.h5", "w") as h5:
        h5["modes"], h5["frequencies_hz"] = modes, [100.0, 200.0, 300.0, 400.0]
    figures = tmp_path / "figures"
    figures.mkdir()
    mine = {"mode_3.png", "mode_003.png", "mode_03.png.bak", "mode_shapes.png"}
    for name in mine:
        (figures / name).write_text("mine")
    stage = SimpleNamespace(figures=(MODES,))
    for n in (3, 1):
        scene = load_scene(SCENE, [f"render.n_modes={n}", "render.window=[64, 48]"])
        assert update_figures(scene, tmp_path, (stage,), Progress(quiet=True)) == ["modes"]
    assert _listing(figures) == set(mode_files(scene)) | mine | {MANIFEST}
    assert set(json.loads((figures / MANIFEST).read_text())["modes"]["files"]) == {"mode_01.png"}
    assert all((figures / name).read_text() == "mine" for name in mine)
