"""Before computing: size estimates against what gmsh and the fem stage really made, the size
guard's refusals (within a second, naming the key to change), and the blade's unit sanity."""
from __future__ import annotations

import dataclasses
import os
import time

import h5py
import numpy as np
import pytest

import pipelines.runner  # noqa: F401  (imported before the timed calls: a second is for the guard)
import pipelines.stages.mesh as mesh_stage
from coarse_runs import clone, coarse_scene_text
from mesh.estimate import ESTIMATE_SPREAD
from mesh.model import BladeMesh
from pipelines import artifacts as art
from pipelines import guard
from pipelines.cli import main
from pipelines.errors import Refused
from pipelines.progress import Progress
from pipelines.runner import plan
from pipelines.scene import load_scene, parse_scene
from pipelines.stages.fem import fem_bytes
from support import R67_TABLE


@pytest.fixture
def machine_24gb(monkeypatch):
    """The reference machine's memory, whatever machine runs the test."""
    monkeypatch.setattr(guard, "machine_memory", lambda: 24e9)


def error_line(capsys) -> str:
    err = capsys.readouterr().err
    lines = [x for x in err.splitlines() if x.strip()]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def test_estimates_against_the_coarse_run(coarse_run):
    scene, out = load_scene(coarse_run[0]), coarse_run[1]
    with h5py.File(out / "mesh.h5") as h5:
        nodes = h5["nodes"].shape[0]
    estimate = mesh_stage._estimated_nodes(scene)
    assert 1 / ESTIMATE_SPREAD < estimate / nodes < ESTIMATE_SPREAD, (estimate, nodes)
    # fem.h5 from the real node count: CSR of K and M plus the mode sets, within 2 %
    assert fem_bytes(scene, nodes) == pytest.approx((out / "fem.h5").stat().st_size, rel=0.02)


def test_the_guard_counts_the_nodes_of_the_current_mesh_only(tmp_path):
    """node_count: the nodes of mesh.h5 when it is this scene's (exact), the estimate from the
    table when mesh.h5 was made from other inputs (a coarser element size: the next run
    meshes again, and the later stages' costs follow the new mesh)."""
    from pipelines.runner import expected_inputs

    scene = parse_scene(coarse_scene_text(), R67_TABLE.parent / "scene.toml")
    h = expected_inputs(scene, ("mesh",))["mesh.h5"][1]
    for recorded, expected in ((h, (1234.0, True)), ("another scene's", (mesh_stage._estimated_nodes(scene), False))):
        with h5py.File(tmp_path / "mesh.h5", "w") as h5:
            h5.attrs["inputs_hash"] = recorded
            h5["nodes"] = np.zeros((1234, 3))
        assert mesh_stage.node_count(scene, tmp_path) == expected


def test_absurd_element_size_is_refused_within_a_second(tmp_path, capsys, machine_24gb):
    scene = tmp_path / "scene.toml"
    scene.write_text(coarse_scene_text().replace("element_size = 0.008", "element_size = 1e-6"))
    t0 = time.perf_counter()
    assert main(["run", str(scene), "--out", str(tmp_path / "out")]) == 2
    assert time.perf_counter() - t0 < 1.0
    line = error_line(capsys)
    assert line.startswith("bladerub: error: [mesh] ~1.1e+14 nodes (estimated) would need ~")
    assert "more than this machine's memory (24 GB): coarsen [mesh] element_size (now 1e-06 m" in line
    assert line.endswith("or pass --yes (or raise [limits] memory_gb) to run it anyway")
    assert not (tmp_path / "out" / "mesh.h5").exists()


def test_500_harmonics_are_refused_within_a_second(coarse_run, tmp_path, capsys, machine_24gb):
    """With mesh, fem (144 MB) and rom current: refused before fem.h5 is read to verify it."""
    scene = clone(coarse_run[1], tmp_path)
    scene.write_text(scene.read_text().replace("n_harmonics = 5\nn_time = 64", "n_harmonics = 500\nn_time = 2048"))
    t0 = time.perf_counter()
    assert main(["run", str(scene), "--out", str(tmp_path), "--until", "hbm"]) == 2
    assert time.perf_counter() - t0 < 1.0
    line = error_line(capsys)
    # (2 N_h + 1) 3 n_b = 1001 * 27 = 27 027 unknowns; the dense fallback's SVD: 10 n_u^2
    # doubles per treatment, and the two run at once where there are two cores
    need = {1: "58.6", 2: "117"}[min(2, len(os.sched_getaffinity(0)))]
    assert line.startswith(f"bladerub: error: [hbm] 2 NFRC(s) of 27 027 unknowns (N_h = 500) would need ~{need} GB")
    assert "lower [hbm] n_harmonics (now 500; the reference is 40)" in line
    assert not (tmp_path / "nfrc_dlft.partial.h5").exists()


def test_refusal_can_be_overridden(coarse_run, machine_24gb):
    scene = load_scene(coarse_run[0])
    big = dataclasses.replace(scene, hbm=dataclasses.replace(scene.hbm, n_harmonics=500, n_time=2048))
    steps = [s for s in plan(big, coarse_run[1], ("mesh", "fem", "rom", "hbm"), verify=False) if s.todo]
    assert [s.stage.name for s in steps] == ["hbm"]
    quiet = Progress(quiet=True)
    with pytest.raises(Refused):
        guard.check_run(big, coarse_run[1], steps, quiet)
    guard.check_run(big, coarse_run[1], steps, quiet, yes=True)  # --yes
    roomy = dataclasses.replace(big, limits=dataclasses.replace(big.limits, memory_gb=128.0))
    guard.check_run(roomy, coarse_run[1], steps, quiet)  # [limits] memory_gb


def test_out_of_core_factor_larger_than_tmpdir_is_refused(coarse_run, tmp_path, monkeypatch, capsys, machine_24gb):
    """[fem] out_of_core writes the Cholesky factor under TMPDIR: a TMPDIR too small for it
    is refused before anything is computed, naming the folder and the key."""
    import shutil
    import tempfile
    from collections import namedtuple

    from pipelines.stages.fem import factor_bytes

    scene = clone(coarse_run[1], tmp_path)
    scene.write_text(scene.read_text().replace("[fem]", "[fem]\nout_of_core = true", 1))
    with h5py.File(tmp_path / "mesh.h5") as h5:
        nodes = h5["nodes"].shape[0]
    need = factor_bytes(nodes)
    tmp, real = tempfile.gettempdir(), shutil.disk_usage
    usage = namedtuple("usage", "total used free")

    def disk_usage(path):
        return usage(1e12, 1e12 - 0.5 * need, 0.5 * need) if str(path) == tmp else real(path)

    monkeypatch.setattr(guard.shutil, "disk_usage", disk_usage)
    # forced: out_of_core leaves the current fem.h5 current (runner.HOW_NOT_WHAT)
    assert main(["run", str(scene), "--out", str(tmp_path), "--until", "fem", "--force"]) == 2
    line = error_line(capsys)
    assert f"writes ~{guard.gb(need)} of temporary files (the out-of-core Cholesky factor) under {tmp}" in line
    assert "point TMPDIR to a larger disk, or set [fem] out_of_core = false" in line
    assert (tmp_path / "fem.h5").is_symlink()  # the current fem.h5 untouched (a run replaces the link)


def test_feet_table_read_as_metres_is_warned(coarse_run, tmp_path, monkeypatch, capsys):
    """A table that states its unit ("THE DIMENSIONS ARE IN FEET.") read in another is refused
    before anything is computed. One that states none, read in the wrong unit: the mesh
    stage warns once, naming the value, the unit it assumed and the unit that fits (gmsh
    replaced by the shared mesh scaled as a metres reading of the feet table would be)."""
    with h5py.File(coarse_run[1] / "mesh.h5") as h5:
        nodes = h5["nodes"][()]
    metres = parse_scene("[blade]\nunits = \"m\"\n")
    assert guard.blade_warnings(load_scene(coarse_run[0]), nodes) == []
    warning, = guard.blade_warnings(metres, nodes / 0.3048)
    tip = np.hypot(nodes[:, 0], nodes[:, 1]).max()  # rotor 67: 0.256 m (the paper's tip radius)
    assert f"read in m ([blade] units = \"m\") has a tip radius of {tip / 0.3048:.3g} m" in warning
    assert f"at 2000 rad/s its tip would move at {2000 * tip / 0.3048:.0f} m/s" in warning
    assert f"Read in ft it would have a tip radius of {tip:.3g} m" in warning

    mesh = art.read_artifact(coarse_run[1] / "mesh.h5", BladeMesh)
    monkeypatch.setattr("pipelines.child.call_in_child",
                        lambda func, *a, **k: dataclasses.replace(mesh, nodes=mesh.nodes / 0.3048))
    scene = tmp_path / "scene.toml"
    scene.write_text(coarse_scene_text().replace('units = "ft"', 'units = "m"'))
    assert main(["run", str(scene), "--out", str(tmp_path / "out"), "--until", "mesh", "--yes"]) == 2
    err = capsys.readouterr().err
    assert "rotor67geometry.dat:50: the table states its lengths in FEET" in err and 'units = "m"' in err
    assert not (tmp_path / "out" / "mesh.h5").exists()

    # the same table without its statement of the unit
    table = tmp_path / "rotor67_no_unit.dat"
    table.write_text("\n".join(line for line in R67_TABLE.read_text().splitlines() if "ARE IN FEET" not in line))
    text = coarse_scene_text().replace('units = "ft"', 'units = "m"')
    scene.write_text(text.replace(str(R67_TABLE), str(table)))
    assert main(["run", str(scene), "--out", str(tmp_path / "out"), "--until", "mesh", "--yes"]) == 0
    err = capsys.readouterr().err
    assert err.count("bladerub: warning: the blade read in m") == 1 and "Read in ft" in err


def test_the_sweep_waits_for_the_nfrcs_when_the_two_would_not_fit_together(coarse_run, tmp_path, capsys):
    """[limits] memory_gb between the larger of the hbm and ti estimates and their sum: each
    stage fits alone, so the run goes on, but the sweep is not started beside the NFRCs."""
    from pipelines.stages import REGISTRY

    if len(os.sched_getaffinity(0)) < 2:
        pytest.skip("the sweep starts beside the NFRCs only with two cores or more")
    scene = clone(coarse_run[1], tmp_path)
    loaded = load_scene(scene)
    need = [REGISTRY[n].estimate(loaded, tmp_path, REGISTRY[n].outputs(loaded)).memory for n in ("hbm", "ti")]
    limit = 0.5 * (max(need) + sum(need))
    scene.write_text(scene.read_text() + f"\n[limits]\nmemory_gb = {limit / 1e9:.4f}\n")
    assert main(["run", str(scene), "--out", str(tmp_path), "--until", "ti"]) == 0
    out = capsys.readouterr().out
    assert f"[ti] waits for hbm: the two at once would need ~{guard.gb(sum(need))} of memory" in out
    assert "beside hbm" not in out and art.verify(tmp_path / "ti.h5") is None


def test_a_sweep_that_cannot_start_fails_in_its_turn_and_the_nfrcs_are_kept(coarse_run, tmp_path, capsys):
    """A Carpenter time step past the ROM's stability limit (8.9e-7 s on the coarse ROM) is
    refused by the sweep; started beside the NFRCs it must not take them down: they are
    computed and kept, and the refusal is the run's error in the ti stage's turn."""
    scene = clone(coarse_run[1], tmp_path)
    # exit 1, a stage failed while computing: the NFRCs were computed (exit 2 says nothing was)
    assert main(["run", str(scene), "--out", str(tmp_path), "--until", "ti", "--set", "ti.dt=2e-6",
                 "--set", "ti.scheme=carpenter"]) == 1
    captured = capsys.readouterr()
    assert "[hbm] done -> nfrc_dlft.h5, nfrc_rl.h5" in captured.out and "[ti] running (no artifact) ..." in captured.out
    errors = [x for x in captured.err.splitlines() if x.startswith("bladerub: error:")]
    assert len(errors) == 1 and "dt_crit = 8.91" in errors[0], captured.err
    assert errors[0].startswith("bladerub: error: stage ti failed: time step") and "nfrc_dlft.h5, nfrc_rl.h5" in errors[0]
    for name in ("nfrc_dlft.h5", "nfrc_rl.h5"):
        assert art.verify(tmp_path / name) is None
    assert not (tmp_path / "ti.h5").exists()


def test_the_disk_a_run_needs_is_the_sum_of_its_stages(tmp_path, monkeypatch, machine_24gb):
    """Three stages that write 40, 30 and 20 MB each fit a folder with 50 MB free, together
    they do not: refused before anything runs, naming the total and the largest stage. With
    60 MB already planned by an earlier call for the same run (`disk`: the runner's second
    call, for the outputs the checksums found damaged), 40 MB more is refused too; --yes
    runs it all."""
    from collections import namedtuple
    from types import SimpleNamespace

    from pipelines.errors import FolderError
    from pipelines.stages.base import Estimate

    def step(name, mb):
        est = Estimate(size="~1 000 nodes", memory=1e6, seconds=1.0, disk=mb * 1e6, advice="")
        return SimpleNamespace(todo=("x",), stage=SimpleNamespace(name=name, estimate=lambda *a: est))

    scene = SimpleNamespace(limits=SimpleNamespace(memory_gb=0.0))
    usage = namedtuple("usage", "total used free")
    real = guard.shutil.disk_usage
    monkeypatch.setattr(guard.shutil, "disk_usage",
                        lambda p: usage(1e12, 1e12 - 50e6, 50e6) if str(p) == str(tmp_path) else real(p))
    log = SimpleNamespace(log=lambda text: None)
    for mb in (40, 30, 20):
        assert guard.check_run(scene, tmp_path, [step("a", mb)], log) == pytest.approx(mb * 1e6)
    with pytest.raises(FolderError, match=r"this run writes ~90 MB \(stage fem: ~40 MB\), 50 MB free"):
        guard.check_run(scene, tmp_path, [step("mesh", 20), step("fem", 40), step("rom", 30)], log)
    with pytest.raises(FolderError, match=r"this run writes ~100 MB \(stage rom: ~40 MB\), 50 MB free"):
        guard.check_run(scene, tmp_path, [step("rom", 40)], log, disk=60e6)
    assert guard.check_run(scene, tmp_path, [step("mesh", 20), step("fem", 40), step("rom", 30)], log,
                           yes=True) == pytest.approx(90e6)
