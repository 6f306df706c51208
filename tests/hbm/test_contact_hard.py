"""Hard cases: grazing contact, stiff/soft contact parameters, many harmonics. Each must
converge, or stop with a recorded reason; a stored point must never be a wrong one (its
residual is recomputed independently of the solver)."""
import numpy as np
import pytest

from hbm.continuation.arclength import ContinuationOptions
from hbm.continuation.newton import NewtonOptions
from hbm.harmonic.nfrc import compute_nfrc
from hbm.options import CasingOptions, ContactOptions, HbmOptions
from support import standin_rom
from test_obstacle import D, F, K, M, W, _solve, C


def test_grazing_contact_converges_to_the_free_orbit(monkeypatch):
    """Obstacle exactly at the peak of the free orbit: penetration ~0, contact force ~0."""
    import test_obstacle as t
    amp = F / np.hypot(K - M * W ** 2, C * W)  # free steady amplitude
    monkeypatch.setattr(t, "D", amp)
    for method in ("rl", "dlft"):
        full, fdof = _solve(method, 16, 1024)
        a1 = np.hypot(full[1, fdof], full[2, fdof])
        # a grazing contact of zero depth cannot change the orbit: relative change at the
        # level of the sampled penetration (the grid misses the exact peak by <~1e-5)
        assert abs(a1 - amp) / amp < 1e-4, method
        assert np.abs(full[3:, fdof]).max() < 1e-4 * amp, method  # no harmonics generated


def _short_nfrc(method, contact, nh=10, nt=256):
    rom = standin_rom()
    hbm = HbmOptions(n_harmonics=nh, n_time=nt, omega_min=400.0, omega_max=410.0)
    cont = ContinuationOptions(omega_min=400.0, omega_max=410.0, ds=0.02, ds_min=1e-4, ds_max=0.05,
                               omega_scale=100.0, max_points=40, newton=NewtonOptions(tol_residual=1e-8))
    casing = CasingOptions(penetration=2e-5)
    return compute_nfrc(rom, casing, contact, hbm, method, continuation=cont), rom, casing, hbm


@pytest.mark.parametrize("method,contact,nh", [
    ("rl", ContactOptions(kappa=1e10), 10),
    ("dlft", ContactOptions(epsilon=1e6), 10),
    ("dlft", ContactOptions(epsilon=1e8), 10),
])
def test_stiff_soft_and_rich_cases_are_honest(method, contact, nh):
    from hbm.harmonic.residual import build_residual
    r, rom, casing, hbm = _short_nfrc(method, contact, nh=nh, nt=max(256, 4 * nh + 2))
    res = build_residual(rom, casing, contact, hbm.__class__(n_harmonics=nh, n_time=max(256, 4 * nh + 2)),
                         method=method)
    assert len(r.omega) >= 1
    for i in np.flatnonzero(r.converged):
        assert np.linalg.norm(res(r.unknowns[i], r.omega[i], jacobian=False)) <= 1e-8 * (1 + 1e-6)
    if r.converged.all():
        assert r.status.startswith("reached omega_max"), r.status
    else:
        assert r.reason[-1] and r.converged[:-1].all(), r.status  # only the last point may fail, with its why


@pytest.mark.parametrize("method", ["rl", "dlft"])
def test_eighty_harmonics_converge_to_the_same_orbit(method):
    """N_h = 80 on the exact 1-dof obstacle problem: converges and agrees with N_h = 32
    to the N_h = 32 truncation error (~2e-5 of the amplitude, see test_obstacle)."""
    from hbm.harmonic.fourier import FourierBasis
    f32, dof = _solve(method, 32, 8192)
    f80, _ = _solve(method, 80, 8192, guess_full=f32)
    x32 = FourierBasis(32, 4096).to_time(f32[:, dof])
    x80 = FourierBasis(80, 4096).to_time(f80[:, dof])
    assert np.abs(x80 - x32).max() / np.abs(x80).max() < 5e-5
