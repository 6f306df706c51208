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


def _plate_artifacts(folder: Path) -> Path:
    """mesh.h5 and fem.h5 of a small plate with two bending modes in `folder`, for the mode
    pictures; returns the (new, empty) figures folder."""
    nodes, cells = plate_tet10(4, 2, 1)
    with h5py.File(folder / "mesh.h5", "w") as h5:
        h5["nodes"], h5["cells"] = nodes, cells
    with h5py.File(folder / "fem.h5", "w") as h5:
        h5["modes"], h5["frequencies_hz"] = bending_modes(nodes), [100.0, 200.0]
    (folder / "figures").mkdir()
    return folder / "figures"


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


def test_mode_pictures_beyond_the_count_go_without_a_manifest(tmp_path):
    """Pictures of a longer drawing that no manifest lists (a run killed between the drawing
    and the manifest's write, a folder of an older version) go too: the stage's own removal,
    not the manifest's, takes every number past the scene's count."""
    figures = _plate_artifacts(tmp_path)
    for i in range(1, 5):
        (figures / f"mode_{i:02d}.png").write_text("earlier")
    scene = load_scene(SCENE, ["render.n_modes=1", "render.window=[64, 48]"])
    assert update_figures(scene, tmp_path, (SimpleNamespace(figures=(MODES,)),), Progress(quiet=True)) == ["modes"]
    assert _listing(figures) == {"mode_01.png", MANIFEST}
    assert (figures / "mode_01.png").read_bytes()[:4] == b"\x89PNG"


def test_a_hand_edited_manifest_never_removes_files_outside_figures(tmp_path):
    """A manifest entry whose recorded names leave figures/ ("../", an absolute path): when
    the figure is drawn again, or declares no file any more, those files stay; only names
    inside figures/ that the figure no longer declares go."""
    figures = _plate_artifacts(tmp_path)
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    mine = [tmp_path / "notes.png", outside / "mode_09.png"]
    for p in mine + [figures / "mode_09.png"]:
        p.write_text("mine")
    recorded = {"../notes.png": "x", str(outside / "mode_09.png"): "x", "mode_09.png": "x"}
    (figures / MANIFEST).write_text(json.dumps({"modes": {"inputs": "an older drawing's", "files": recorded}}))
    stage = SimpleNamespace(figures=(MODES,))
    scene = load_scene(SCENE, ["render.n_modes=1", "render.window=[64, 48]"])
    assert update_figures(scene, tmp_path, (stage,), Progress(quiet=True)) == ["modes"]
    assert _listing(figures) == {"mode_01.png", MANIFEST}
    assert all(p.read_text() == "mine" for p in mine)
    (figures / MANIFEST).write_text(json.dumps({"modes": {"inputs": "x", "files": recorded}}))
    scene = load_scene(SCENE, ["render.n_modes=0"])
    assert update_figures(scene, tmp_path, (stage,), Progress(quiet=True)) == []
    assert all(p.read_text() == "mine" for p in mine)


def test_no_files_declared_any_more_removes_the_last_drawing(tmp_path):
    """render.n_modes = 0 declares no mode picture: those of the last drawing went on reading
    as this scene's (the figure was skipped, its files and manifest entry kept)."""
    figures = _plate_artifacts(tmp_path)
    (figures / "mode_shapes.png").write_text("mine")
    stage = SimpleNamespace(figures=(MODES,))
    scene = load_scene(SCENE, ["render.n_modes=2", "render.window=[64, 48]"])
    assert update_figures(scene, tmp_path, (stage,), Progress(quiet=True)) == ["modes"]
    assert {"mode_01.png", "mode_02.png"} <= _listing(figures)
    scene = load_scene(SCENE, ["render.n_modes=0", "render.window=[64, 48]"])
    assert update_figures(scene, tmp_path, (stage,), Progress(quiet=True)) == []
    assert _listing(figures) == {"mode_shapes.png", MANIFEST}
    assert "modes" not in json.loads((figures / MANIFEST).read_text())


def test_a_series_under_another_stem_removes_the_old_one(tmp_path):
    """The ParaView series is named after the first of hbm.methods: with ["dlft", "rl"] after
    ["rl", "dlft"], hbm_rl.pvd and its snapshots stayed beside hbm_dlft's; with hbm_instants = 0
    both stayed. Only files the manifest recorded go, and the folder they leave empty."""
    from pipelines.stages.base import Figure

    (tmp_path / "nfrc.h5").write_text("input")

    def draw(ctx):
        for name in _instants_files(ctx.scene):
            (ctx.out / "figures" / name).parent.mkdir(parents=True, exist_ok=True)
            (ctx.out / "figures" / name).write_text(name)

    fig = Figure("series", files=_instants_files, depends=("render.hbm_instants", "hbm.methods"),
                 inputs=lambda s: ("nfrc.h5",), draw=draw)
    stage = SimpleNamespace(figures=(fig,))
    figures = tmp_path / "figures"
    (figures / "hbm_rl").mkdir(parents=True)
    (figures / "hbm_rl" / "notes.txt").write_text("mine")
    scene = load_scene(SCENE, ["render.hbm_instants=3", 'hbm.methods=["rl", "dlft"]'])
    assert update_figures(scene, tmp_path, (stage,), Progress(quiet=True)) == ["series"]
    old = set(_instants_files(scene))
    assert old <= _listing(figures) and "hbm_rl.pvd" in old
    scene = load_scene(SCENE, ["render.hbm_instants=2", 'hbm.methods=["dlft", "rl"]'])
    assert update_figures(scene, tmp_path, (stage,), Progress(quiet=True)) == ["series"]
    assert _listing(figures) == set(_instants_files(scene)) | {"hbm_rl/notes.txt", MANIFEST}
    scene = load_scene(SCENE, ["render.hbm_instants=0", 'hbm.methods=["dlft", "rl"]'])
    update_figures(scene, tmp_path, (stage,), Progress(quiet=True))
    assert _listing(figures) == {"hbm_rl/notes.txt", MANIFEST}
    assert not (figures / "hbm_dlft").exists()
