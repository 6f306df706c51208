"""The subharmonic option [hbm] subharmonic = nu: harmonics of Omega / nu.

A basis of Omega / 2 holds every Omega-periodic orbit on its even harmonics. So the nu = 1
solution of the rotor 67 ROM (N_h harmonics), embedded in the nu = 2 basis with
N_h' = 2 N_h + 1 harmonics (branch switching's) or 2 N_h (the isola search's doubled basis;
RL's Lanczos factors are those of the frequencies k Omega / nu, so the same in both), must
solve the nu = 2 equations to the FFT's round-off:
this checks the casing sampled at nu tau, the velocity scaled by Omega / nu, friction's
rho Omega and the harmonic Z blocks at k Omega / nu. The nu = 2
Jacobians must match finite differences (dR/dOmega has the 1 / nu chain rule), and a
nu = 2 continuation started from it must trace the same curve as the nu = 1 one.
"""

import numpy as np
import pytest

from hbm.harmonic.nfrc import compute_nfrc
from hbm.harmonic.residual import build_residual
from hbm.harmonic.solver import HbmSolver
from hbm.harmonic.start import solve_start
from hbm.harmonic.nfrc import default_continuation
from hbm.options import CasingOptions, ContactOptions, HbmOptions
from hbm.stability.switching import embed_harmonics
from support import coarse_rom, distance_to_polyline

NH, NT, OMEGA = 8, 128, 2000.0


@pytest.fixture(scope="module")
def rom():
    return coarse_rom()


@pytest.mark.parametrize("nh2", [2 * NH + 1, 2 * NH])
@pytest.mark.parametrize("method", ["dlft", "rl"])
def test_embedded_omega_periodic_solution_solves_the_nu_2_equations(rom, method, nh2):
    o1 = HbmOptions(n_harmonics=NH, n_time=NT, omega_min=1800.0, omega_max=OMEGA)
    r1 = build_residual(rom, CasingOptions(), ContactOptions(), o1, method=method)
    u1, note = solve_start(r1, OMEGA, default_continuation(o1), HbmSolver())
    R1 = r1(u1, OMEGA, jacobian=False)
    assert np.linalg.norm(R1) < 1e-8, note
    o2 = HbmOptions(n_harmonics=nh2, n_time=2 * NT, subharmonic=2)
    r2 = build_residual(rom, CasingOptions(), ContactOptions(), o2, method=method)
    u2 = embed_harmonics(u1, r2.n_r, 2, nh2)
    R2 = r2(u2, OMEGA, jacobian=False)
    # the same equations on twice the samples of a twice longer period: equal to round-off
    # (the FFTs and sums of 2 N_t samples, ||u|| ~ 60): 1e-10 absolute, against 1e-8 for
    # Newton's own test
    assert np.linalg.norm(R2) < 1e-10, np.linalg.norm(R2)
    # and its even rows are the nu = 1 residual's rows (harmonic k of Omega = 2k of Omega/2)
    assert np.allclose(R2.reshape(-1, r2.n_r)[0::4][: NH // 2 + 1], 0.0, atol=1e-10)


@pytest.mark.parametrize("method", ["dlft", "rl"])
def test_nu_2_jacobians_match_finite_differences(rom, method):
    o2 = HbmOptions(n_harmonics=6, n_time=64, subharmonic=2)
    r2 = build_residual(rom, CasingOptions(), ContactOptions(), o2, method=method)
    rng = np.random.default_rng(1)
    u = rng.standard_normal(r2.size) * 0.5  # odd harmonics too: a genuinely nu = 2 state
    u[:r2.n_r] += 0.3  # mean radial offset towards the casing: contact on some samples
    w = 1500.0
    R, J, dw = r2(u, w)
    h = 1e-6
    v = rng.standard_normal(r2.size)
    fd = (r2(u + h * v, w, jacobian=False) - r2(u - h * v, w, jacobian=False)) / (2 * h)
    # central differences on a piecewise-smooth residual (DLFT's max, RL's penalty): error
    # O(h^2 |R'''|) away from kinks; 1e-6 relative as in tests/hbm/test_jacobians.py
    assert np.linalg.norm(J @ v - fd) < 1e-6 * np.linalg.norm(fd)
    hw = 1e-3
    fdw = (r2(u, w + hw, jacobian=False) - r2(u, w - hw, jacobian=False)) / (2 * hw)
    assert np.linalg.norm(dw - fdw) < 1e-6 * np.linalg.norm(fdw)


def test_nu_2_continuation_traces_the_nu_1_curve(rom):
    o1 = HbmOptions(n_harmonics=NH, n_time=NT, omega_min=1900.0, omega_max=OMEGA)
    o2 = HbmOptions(n_harmonics=2 * NH + 1, n_time=2 * NT, omega_min=1900.0, omega_max=OMEGA, subharmonic=2)
    a = compute_nfrc(rom, CasingOptions(), ContactOptions(), o1, "dlft", stability=False)
    u2 = embed_harmonics(a.unknowns[0], 3 * rom.n_boundary, 2, 2 * NH + 1)
    b = compute_nfrc(rom, CasingOptions(), ContactOptions(), o2, "dlft", stability=False, guess=(OMEGA, u2))
    assert a.status == b.status == "reached omega_min"
    # same Omega-periodic branch: the nu = 2 run keeps its odd harmonics at the level of
    # Newton's tolerance (1e-8 on the scaled residual: measured 3e-9 of the largest
    # harmonic), where a genuinely period-doubled orbit has them at percents: 1e-6 ...
    x = b.harmonics  # (m, 2 N_h + 1, n_r), basis Omega / 2
    odd = np.abs(x[:, 1::4]).max() + np.abs(x[:, 2::4]).max()
    assert odd < 1e-6 * np.abs(x).max()
    # ... and its (Omega, LE amplitude) curve is the nu = 1 one: both are polylines through
    # points of one curve (at other arc lengths: the metric sees twice the unknowns), so
    # each nu = 2 point must lie on the nu = 1 polyline, in the units of the continuation
    # (Omega / 100 rad/s) and of the largest amplitude. Chords between points ~0.1-0.5
    # units apart sag from the curve by ~1e-3 of that there: 5e-3 leaves room.
    scale = np.array([100.0, a.le_amplitude.max()])
    pa = np.column_stack([a.omega, a.le_amplitude]) / scale
    pb = np.column_stack([b.omega, b.le_amplitude]) / scale
    assert distance_to_polyline(pb, pa).max() < 5e-3
    assert distance_to_polyline(pa, pb).max() < 5e-3
    assert abs(b.le_amplitude.max() - a.le_amplitude.max()) < 1e-3 * a.le_amplitude.max()


def test_scene_keys_subharmonic_and_stability():
    from pipelines.scene import SceneError, parse_scene

    s = parse_scene("[hbm]\nsubharmonic = 2\nstability = true\n")
    assert s.hbm.subharmonic == 2 and s.hbm.stability is True
    assert parse_scene("").hbm.subharmonic == 1
    for bad, msg in (("subharmonic = 0", r"subharmonic must be (an integer )?>= 1, got 0"),
                     ("subharmonic = 1.5", r"\[hbm\] subharmonic must be an integer"),
                     ("stability = 1", r"\[hbm\] stability must be true or false")):
        with pytest.raises(SceneError, match=msg):
            parse_scene(f"[hbm]\n{bad}\n")
