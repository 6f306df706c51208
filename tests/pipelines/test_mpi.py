"""`mpirun -n 2 bladerub run SCENE --until rom` against one process, on a small rotor 67 scene.

The two runs share nothing but the mesh file (the MPI run meshes on rank 0, the serial run
finds that mesh.h5 up to date): the MPI run assembles on a partitioned dolfinx mesh,
permutes K and M into the serial free-dof numbering, factorises with MUMPS over two ranks
and gathers the modes; the serial run does none of that. Skipped only where `mpirun` is
not installed.
"""
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import h5py
import numpy as np
import pytest

from pipelines.cli import main
from pipelines.stages.fem import factor_bytes
from support import needs_mpirun

ROOT = Path(__file__).resolve().parents[2]
COARSE = ROOT / "scenes" / "rotor67_coarse.toml"
MPIRUN = shutil.which("mpirun")
pytestmark = needs_mpirun


def _mpirun(n: int, *args: str, timeout: float = 300, **env) -> subprocess.CompletedProcess:
    """`mpirun -n n python args...` with this checkout first on the path. Open MPI refuses
    root without the two ALLOW_RUN_AS_ROOT variables (CI containers run as root) and more
    ranks than cores without oversubscription (2 ranks on a 1-core runner); other MPIs
    ignore these variables. The timeout turns a deadlock into a failure."""
    env = dict(os.environ, PYTHONPATH=str(ROOT), OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1", **env)
    return subprocess.run([MPIRUN, "-n", str(n), sys.executable, *args], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=timeout)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("mpi")
    scene = tmp / "scene.toml"
    text = COARSE.read_text().replace("../../shared", str(ROOT.parent / "shared"))
    # a coarser blade than the coarse scene (~15 000 nodes, ~43 000 dof) and no PNGs: the
    # comparison needs a real blade, not a large one
    text = text.replace("size_growth = 0.5", "size_growth = 1.0").replace("n_modes = 6", "n_modes = 0")
    scene.write_text(text)
    par, ser = tmp / "mpi", tmp / "serial"
    proc = _mpirun(2, "-m", "pipelines.cli", "run", str(scene), "--out", str(par), "--until", "rom")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    ser.mkdir()
    shutil.copy(par / "mesh.h5", ser / "mesh.h5")
    assert main(["run", str(scene), "--out", str(ser), "--until", "rom"]) == 0
    return par, ser, proc.stdout


def _read(path: Path, *names):
    with h5py.File(path, "r") as h5:
        return [h5[n][()] for n in names]


def test_frequencies_and_modes_match_one_process(runs):
    par, ser, _ = runs
    names = ("frequencies", "fixed_interface_frequencies", "modes", "constraint_modes", "fixed_interface_modes")
    for name, a, b in zip(names, _read(par / "fem.h5", *names), _read(ser / "fem.h5", *names)):
        # Both runs do the same block Krylov iteration (same start block, same numbering,
        # same eigenvector sign rule); they differ by round-off only: MUMPS eliminates in
        # another order on two ranks and the sums run in another order. Measured ~1e-12;
        # 1e-8 is the bound (the eigen-solver's own tolerance is 1e-10).
        assert a.shape == b.shape, name
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-8 * np.abs(b).max(), err_msg=name)
    f_par, f_ser = _read(par / "fem.h5", "frequencies")[0][:6], _read(ser / "fem.h5", "frequencies")[0][:6]
    np.testing.assert_allclose(f_par, f_ser, rtol=1e-8)


def test_stiffness_and_mass_match_one_process(runs):
    par, ser, _ = runs
    for m in ("K", "M"):
        names = (f"{m}/indptr", f"{m}/indices", f"{m}/data")
        (ip, ix, d), (ip0, ix0, d0) = _read(par / "fem.h5", *names), _read(ser / "fem.h5", *names)
        np.testing.assert_array_equal(ip, ip0)  # same pattern in the serial numbering
        np.testing.assert_array_equal(ix, ix0)
        # the same element matrices, summed in another order where partitions meet:
        # a few ulps of the largest entry
        np.testing.assert_allclose(d, d0, rtol=0, atol=1e-14 * np.abs(d0).max(), err_msg=m)


def test_rom_matches_one_process(runs):
    par, ser, _ = runs
    names = ("K", "M", "C", "frequencies")
    for name, a, b in zip(names, _read(par / "rom.h5", *names), _read(ser / "rom.h5", *names)):
        # what the HBM stage reads: to the 1e-8 of the largest entry (see above)
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-8 * np.abs(b).max(), err_msg=name)


def test_out_of_core_factor_on_two_ranks_matches_one_process_in_core(runs, tmp_path):
    """[fem] out_of_core under mpirun: each rank's MUMPS writes its part of the factor to
    files under TMPDIR and reads it back at every block solve; the FEM results equal the
    serial in-core run's, and the temporary folders are gone afterwards."""
    par, ser, _ = runs
    scene = tmp_path / "scene.toml"
    text = (par.parent / "scene.toml").read_text()
    assert "[fem]" in text
    scene.write_text(text.replace("[fem]", "[fem]\nout_of_core = true", 1))
    out, scratch = tmp_path / "ooc", tmp_path / "scratch"
    out.mkdir()
    scratch.mkdir()
    shutil.copy(par / "mesh.h5", out / "mesh.h5")
    proc = _mpirun(2, "-m", "pipelines.cli", "run", str(scene), "--out", str(out), "--until", "fem", TMPDIR=str(scratch))
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "free dof on 2 MPI ranks" in proc.stdout
    with h5py.File(out / "fem.h5", "r") as h5:
        # the factor was in files (both ranks' together), of about the size the guard plans
        # for (pipelines.stages.fem.factor_bytes, an upper bound for table meshes)
        mb, nodes = h5.attrs["factor_files_mb"], len(_read(out / "mesh.h5", "nodes")[0])
    assert 0.1 * factor_bytes(nodes) / 1e6 < mb <= factor_bytes(nodes) / 1e6, (mb, nodes)
    names = ("frequencies", "fixed_interface_frequencies", "modes", "constraint_modes", "fixed_interface_modes")
    for name, a, b in zip(names, _read(out / "fem.h5", *names), _read(ser / "fem.h5", *names)):
        assert a.shape == b.shape, name  # the bound of test_frequencies_and_modes_match_one_process
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-8 * np.abs(b).max(), err_msg=name)
    assert not list(scratch.iterdir()), "the out-of-core factor's files were left behind"


def test_distributed_run_speaks_once_and_says_so(runs):
    par, _, out = runs
    # rank 0 alone reports (one banner per stage) and the FEM stage ran on both ranks
    assert out.count("[mesh] running") == 1 and out.count("[fem] running") == 1 and out.count("[rom] running") == 1
    assert "free dof on 2 MPI ranks" in out
    with h5py.File(par / "fem.h5", "r") as h5:
        assert "time_gather_s" in h5.attrs  # the gather to rank 0 exists only on the distributed path
    assert not list(par.glob(".*tmp*")), "temporary files left behind"


def test_failure_on_rank_zero_ends_every_rank(tmp_path):
    # a missing geometry file: rank 0 finds it out while deciding the mesh stage; the
    # other rank must not wait forever, and the message is printed once
    scene = tmp_path / "bad.toml"
    scene.write_text(COARSE.read_text().replace("../../shared/data/rotor67/rotor67geometry.dat", "nowhere.dat"))
    proc = _mpirun(2, "-m", "pipelines.cli", "run", str(scene), "--out", str(tmp_path / "out"), "--until", "rom",
                   timeout=120)
    assert proc.returncode != 0
    assert proc.stderr.count("geometry file not found") == 1, proc.stderr
    assert not (tmp_path / "out" / "mesh.h5").exists()


def test_cholmod_asked_for_under_mpirun_is_refused_before_anything_is_written(tmp_path):
    # CHOLMOD factorises on one process: [fem] solver = "cholmod" under mpirun is refused
    # with exit 2, once, naming the key, before the output folder is made
    proc = _mpirun(2, "-m", "pipelines.cli", "run", str(COARSE), "--out", str(tmp_path / "out"), "--until", "rom",
                   "--set", "fem.solver=cholmod", timeout=120)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert proc.stderr.count('[fem] solver "cholmod" factorises on one process') == 1, proc.stderr
    assert not (tmp_path / "out").exists()


def test_rank_helpers_run_where_they_should(tmp_path):
    # on_root: rank 0 alone runs the step, every rank gets its value; on_all: a failure on
    # rank 1 reaches rank 0 as RankFailed naming rank 1 and the message
    script = tmp_path / "ranks.py"
    script.write_text(textwrap.dedent(f"""
        from pathlib import Path
        from pipelines.parallel import RankFailed, on_all, on_root, world
        comm = world()
        out = Path({str(tmp_path)!r})
        value = on_root(comm, lambda: (out / f"ran_{{comm.rank}}").write_text("x") and comm.rank + 42)
        assert value == 42, value
        def step():
            if comm.rank == 1:
                raise ValueError("rank one refuses")
            return "fine"
        try:
            on_all(comm, step)
        except RankFailed as exc:
            (out / f"relay_{{comm.rank}}").write_text(str(exc))
        except ValueError as exc:
            (out / f"own_{{comm.rank}}").write_text(str(exc))
        """))
    proc = _mpirun(2, str(script), timeout=120)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert sorted(p.name for p in tmp_path.glob("ran_*")) == ["ran_0"]
    assert (tmp_path / "relay_0").read_text() == "rank 1 failed: ValueError: rank one refuses"
    assert (tmp_path / "own_1").read_text() == "rank one refuses"
