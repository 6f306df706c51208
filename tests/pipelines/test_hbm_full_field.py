"""The hbm stage's ParaView instants of one NFRC point span the basis period 2 pi nu / Omega
(nu = [hbm] subharmonic), and each is the recovery matrix applied to the ROM dof there."""
from dataclasses import replace

import numpy as np
import pytest

from hbm.harmonic.residual import build_residual
from hbm.options import CasingOptions, ContactOptions, HbmOptions
from pipelines.stages.hbm import full_field_instants
from support import standin_rom


@pytest.mark.parametrize("nu, n", [(1, 8), (2, 8), (3, 8), (1, 4)])
def test_full_field_instants_span_the_period_of_a_subharmonic_basis(nu, n):
    # [hbm] subharmonic = nu: the unknowns hold harmonics of Omega / nu, so one period of the
    # orbit is 2 pi nu / Omega (nu revolutions); the ParaView series (write_hbm_vtu builds its
    # residual from the scene's [hbm]) must carry those times, as the residual's own signals do;
    # fewer instants (4) than the 2 N_h + 1 = 7 coefficients: the same instants of the orbit
    rom = standin_rom()
    rng = np.random.default_rng(1)
    rom = replace(rom, recovery=rng.standard_normal((3 * 20, rom.K.shape[0])).astype(np.float32))
    res = build_residual(rom, CasingOptions(), ContactOptions(),
                         HbmOptions(n_harmonics=3, n_time=16, subharmonic=nu), method="dlft")
    u = 1e-3 * rng.standard_normal(res.size)
    omega = 1500.0
    t, disp = full_field_instants(rom, res, u, omega, n)
    expected = np.arange(n) * 2 * np.pi * nu / (omega * n)
    np.testing.assert_allclose(t, expected, rtol=1e-12, atol=0)
    sig = res.signals(u, omega, n_time=8)  # every 8 // n-th of them
    np.testing.assert_allclose(t, sig["t"][::8 // n], rtol=1e-12, atol=0)
    field = (np.asarray(rom.recovery, dtype=np.float64) @ sig["displacement"][::8 // n].T).T.reshape(n, -1, 3)
    np.testing.assert_allclose(disp, field, rtol=1e-9, atol=1e-12 * np.abs(field).max())


def test_the_point_written_is_a_converged_one():
    """The NFRC point of the ParaView files: the converged point of largest LE amplitude, or
    the converged point nearest [render] hbm_omega; a failed last point (the one that ended
    the branch, its amplitude that of a diverged iterate) is never it; none converged: an
    error that says so."""
    from types import SimpleNamespace

    from pipelines.stages.hbm import chosen_point

    def stored(converged):
        branch = SimpleNamespace(omega=np.array([2000.0, 1990.0, 1980.0, 1975.0]), converged=np.array(converged))
        return SimpleNamespace(branch=branch, extras={"le_amplitude": np.array([1e-4, 3e-4, 2e-4, 9e-3])})

    s = stored([True, True, True, False])
    assert chosen_point(s, None) == 1
    assert chosen_point(s, 1976.0) == 2
    assert chosen_point(stored([True, False, True, True]), None) == 3
    with pytest.raises(ValueError, match="no converged point"):
        chosen_point(stored([False] * 4), None)





def test_an_nfrc_that_never_starts_fails_its_paraview_figure_alone(coarse_nfrc, tmp_path, monkeypatch, capsys):
    """No start strategy converges at either end of the range (here made so: the strategies
    give a guess of NaN). The NFRC file holds the one failed point, its status, and in its
    detail each end's strategies and why they failed, which the run's warning repeats (the
    status alone gave the continuation's last Newton). The ParaView instants of "an NFRC
    point" cannot be written: the run used to end there with exit 2 ("nothing was
    computed") and the bare "the NFRC has no converged point to write", the figures after it
    undrawn. Now that figure alone fails, named with the NFRC's status and the scene's way
    out, exit 1, and the way out ends the run."""
    import h5py

    from coarse_runs import clone
    from hbm.harmonic import nfrc as nfrc_module
    from pipelines.branch_store import load_branch
    from pipelines.cli import main

    def nowhere(res, omega, opts, solver):
        return np.full(res.size, np.nan), f"no start found: made to fail at {omega:g}"

    monkeypatch.setattr(nfrc_module, "solve_start", nowhere)  # one treatment: computed in this process
    out = tmp_path / "out"
    scene = clone(coarse_nfrc[1], out)
    # the clone's ParaView series of a converged point: the figure's last drawing, which stays
    n_left = 1 + len(list((out / "figures" / "hbm_dlft").glob("hbm_dlft_*.vtu")))
    assert n_left > 3
    run = ["run", str(scene), "--out", str(out), "--until", "hbm", "--quiet", "--set", 'hbm.methods=["dlft"]',
           "--set", "hbm.max_points=3999", "--set", "render.n_modes=0"]
    assert main(run) == 1
    branch = load_branch(out / "nfrc_dlft.h5").branch
    assert not branch.converged.any() and branch.status.startswith("start point did not converge: ")
    with h5py.File(out / "nfrc_dlft.h5", "r") as h5:
        detail = h5.attrs["detail"]
    assert detail == ("no start point: at omega=2000: no start found: made to fail at 2000; "
                      "at omega=1900: no start found: made to fail at 1900")
    err = capsys.readouterr().err.splitlines()
    assert f"bladerub: warning: the dlft NFRC has {detail}" in err
    assert [line for line in err if line.startswith("bladerub: error: ")] == [
        f"bladerub: error: figure hbm_vtu failed: nfrc_dlft.h5: the NFRC has no converged point to write (its status: "
        f"{branch.status}); or write no NFRC point for ParaView in runs: [render] hbm_instants = 0 (its last drawing "
        f"stays, from other inputs: figures/hbm_dlft.pvd, figures/hbm_dlft/hbm_dlft_000.vtu and {n_left - 2} more); "
        f"kept: mesh.h5, fem.h5, rom.h5, nfrc_dlft.h5"]
    assert main(run + ["--set", "render.hbm_instants=0"]) == 0


def test_an_nfrc_that_ends_where_it_started_says_which_stretch_it_leaves_empty(coarse_nfrc, tmp_path, capsys):
    """Past the friction lock (mu = 0.25 > mu_set = 0.123 on the coarse ROM) RL's branch at
    N_h = 10 starts at 2000 rad/s by the friction homotopy, turns back near 1964 rad/s and
    leaves the range at 2000 rad/s again (measured: 54 points). Its status alone, "reached
    omega_max", reads as a complete NFRC; the file's detail and the run's warning say which
    stretch of the range holds none of its points. DLFT, which crosses the range, has none."""
    import h5py

    from coarse_runs import clone
    from pipelines.branch_store import load_branch
    from pipelines.cli import main

    out = tmp_path / "out"
    scene = clone(coarse_nfrc[1], out)
    run = ["run", str(scene), "--out", str(out), "--until", "hbm", "--quiet", "--set", "contact.mu=0.25",
           "--set", "hbm.n_harmonics=10", "--set", "hbm.n_time=128", "--set", "render.n_modes=0",
           "--set", "render.hbm_instants=0"]
    assert main(run) == 0
    err = capsys.readouterr().err
    rl = load_branch(out / "nfrc_rl.h5").branch
    w = rl.omega[rl.converged]
    assert rl.status == "reached omega_max" and w[0] == 2000.0 and 1950.0 < w.min() < 1990.0
    with h5py.File(out / "nfrc_rl.h5", "r") as h5:
        detail = h5.attrs["detail"]
    assert detail == (f"turned back at {w.min():.1f} rad/s and ended where it started (2000 rad/s): "
                      f"1900.0-{w.min():.1f} rad/s holds none of its points (the isola search, --until isolas, "
                      "looks there for other branches)")
    assert f"bladerub: warning: the rl NFRC {detail}" in err
    dlft = load_branch(out / "nfrc_dlft.h5").branch
    assert dlft.status == "reached omega_min" and dlft.detail == "" and "the dlft NFRC" not in err
