"""How the isola search builds its seeds, against constructions made here.

Modal seeds (eq. (31), hbm.isolas.harmonic.modal_seeds): x0(t) = A rho_tip Phi_j cos(k Omega t),
Phi_j the ROM's j-th mode (scipy.linalg.eigh(K, M)) scaled to a largest radial displacement of 1
over the contact nodes, rho_tip their mean radius, A dimensionless: the seed's time signal is
built here by a cosine sum on the coarse rotor 67 ROM and compared with the HBM unknowns the
code makes, in the basis of Omega (nu = 1) and of Omega / 2 (nu = 2, where k Omega is the basis'
harmonic 2 k). Seeds from time integration (ti_seeds): the fit of a synthetic orbit with phased
harmonics against numpy's FFT and the closed-form coefficients.
"""
from types import SimpleNamespace

import numpy as np
import pytest
import scipy.linalg as sla

from hbm.isolas.harmonic import HbmProblem, modal_seeds, ti_seeds
from hbm.isolas.options import IsolaOptions
from hbm.options import CasingOptions, ContactOptions, HbmOptions
from support import coarse_rom

OMEGA = 960.0  # rad/s


@pytest.fixture(scope="module")
def rom():
    return coarse_rom()


def _residual(rom, nu, n_harmonics):
    hbm = HbmOptions(subharmonic=nu, n_harmonics=n_harmonics, n_time=64 * nu)
    return HbmProblem(rom, CasingOptions(), ContactOptions(), hbm, "dlft")()[0]


@pytest.mark.parametrize("nu", [1, 2])
def test_modal_seeds_are_A_rho_tip_phi_cos_k_omega_t(rom, nu):
    res = _residual(rom, nu, 10 * nu)  # every default harmonic k <= 10 of Omega fits
    iso = IsolaOptions()
    seeds = modal_seeds(res, rom, iso, np.array([OMEGA]))
    assert len(seeds) == 4 * 10 * 3  # modes x harmonics x amplitudes, README
    nb = rom.n_boundary
    lam, vec = sla.eigh(rom.K, rom.M)
    rho_tip = np.mean(rom.rho)
    assert rho_tip == pytest.approx(0.240946, abs=1e-6)  # the coarse ROM's nine contact radii
    nt = res.basis.n_time
    t = np.arange(nt) * (2 * np.pi * nu / OMEGA) / nt  # the basis' samples over nu revolutions, s
    i = 0
    for j in range(4):
        phi = vec[: 3 * nb, j]
        phi = phi / phi[0::3][np.argmax(np.abs(phi[0::3]))]  # largest radial one: +1
        for k in iso.harmonics:
            for a in iso.amplitudes:
                sd = seeds[i]
                i += 1
                assert sd.omega == OMEGA and sd.origin == f"modal j={j + 1} k={k} A={a:.2g}"
                ref = a * rho_tip * np.outer(np.cos(k * OMEGA * t), phi)  # (N_t, 3 n_b), m
                sig = res.basis.to_time(res.to_coefficients(sd.x))
                np.testing.assert_allclose(sig, ref, rtol=0, atol=1e-9 * a * rho_tip)
                # the first four modes' largest radial displacement is at the LE (node 0)
                assert 0.5 * np.ptp(sig[:, 0]) == pytest.approx(a * rho_tip, rel=1e-9)
                assert np.abs(sig[:, 0::3]).max() == pytest.approx(a * rho_tip, rel=1e-9)


def test_modal_seeds_leave_out_the_harmonics_of_omega_beyond_the_basis(rom):
    # nu = 2, N_h = 12 harmonics of Omega / 2: k Omega up to k = 6
    seeds = modal_seeds(_residual(rom, 2, 12), rom, IsolaOptions(), np.array([OMEGA]))
    assert len(seeds) == 4 * 6 * 3
    assert {int(s.origin.split()[2][2:]) for s in seeds} == set(range(1, 7))


@pytest.mark.parametrize("nu, n_harmonics, count", [(1, 40, 4920), (2, 12, 2952), (2, 40, 4920)])
def test_the_stage_estimate_counts_the_modal_seeds(nu, n_harmonics, count):
    from pipelines.stages.isolas import _estimate

    # 4 modes x (harmonics k of Omega with k nu <= N_h) x 3 amplitudes x 41 speeds
    scene = SimpleNamespace(isolas=IsolaOptions(workers=1),
                            hbm=HbmOptions(subharmonic=nu, n_harmonics=n_harmonics, n_time=4 * n_harmonics),
                            mesh=SimpleNamespace(n_boundary=9), n_contact_nodes=9)
    assert _estimate(scene, None, None).size == f"{count} seeds per treatment"


def test_ti_seed_is_the_orbit_fourier_series_from_a_whole_revolution():
    """A sweep point whose stored window starts at the march's revolution 35 (Omega t = 70 pi:
    the casing where it is at t = 0); nu = 2 over two revolutions, which start at Omega t / 2
    = 35 pi: the fit is the orbit shifted by one revolution (odd harmonics of Omega / 2
    negated), itself a solution."""
    n_h, spr, w = 12, 64, 1234.0
    for nu, p in ((1, 2), (2, 4)):
        res = SimpleNamespace(nu=nu, basis=SimpleNamespace(n_harmonics=n_h), n_c=2 * n_h + 1, n_r=1,
                              to_unknowns=lambda xr: np.asarray(xr, float).reshape(-1))
        m = np.arange(32 * spr, 37 * spr)  # samples of revolutions 32 to 36
        times = 2 * np.pi * m / (w * spr)
        tau = w * times[-2 * spr:] / nu  # basis angle of the last two revolutions
        # a mean, cos(tau + 0.7), sin(3 tau - 1.1) and harmonic 17, beyond N_h
        sig = 1e-5 + 3e-4 * np.cos(tau + 0.7) + 1e-4 * np.sin(3 * tau - 1.1) + 2e-5 * np.cos(17 * tau)
        sweep = SimpleNamespace(omega=np.array([w]), period=np.array([p]), period_class=np.array([1]),
                                times=times[None], boundary=sig[None, :, None])
        (sd,) = ti_seeds(res, sweep, (400.0, 2000.0), 2)
        s = sig[-nu * spr:]
        f = np.fft.rfft(s) / len(s)
        fft = np.r_[f[0].real, np.ravel(np.column_stack([2 * f[1:n_h + 1].real, -2 * f[1:n_h + 1].imag]))]
        np.testing.assert_allclose(sd.x, fft, rtol=0, atol=1e-16)
        # closed form, from the window's own first sample (shifted by pi for nu = 2)
        shift = np.pi if nu == 2 else 0.0
        exact = np.zeros(2 * n_h + 1)
        exact[0] = 1e-5
        exact[1], exact[2] = 3e-4 * np.cos(0.7 + shift), -3e-4 * np.sin(0.7 + shift)
        exact[5], exact[6] = 1e-4 * np.sin(-1.1 + 3 * shift), 1e-4 * np.cos(-1.1 + 3 * shift)
        np.testing.assert_allclose(sd.x, exact, rtol=0, atol=1e-15)
