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
from hbm.isolas.membership import KnownBranch
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
    assert len(seeds) == 4 * 10 * 3  # modes x harmonics x amplitudes, README; no branch around
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


def test_seeds_around_a_branch_add_the_shapes_to_its_points_at_each_speed(rom):
    """A branch through OMEGA three times (a fold each way), one point exactly on it: the
    second family adds the same shapes, with primary_amplitudes, to each of the three points,
    the chord's crossings interpolated linearly in omega by hand here."""
    res = _residual(rom, 1, 10)
    n = res.to_unknowns(np.zeros((res.n_c, res.n_r))).size
    rng = np.random.default_rng(3)
    om = np.array([900.0, 950.0, 1000.0, 970.0, OMEGA, 940.0, 980.0, 1010.0])
    x = rng.standard_normal((len(om), n)) * 1e-3
    branch = KnownBranch.of(om, x, "primary DLFT NFRC")
    iso = IsolaOptions(primary_amplitudes=(1e-3, 2e-3))
    plain = modal_seeds(res, rom, iso, np.array([OMEGA]))
    seeds = modal_seeds(res, rom, iso, np.array([OMEGA, 2000.0]), around=(branch,))
    at = seeds[:len(seeds) - len(plain)]  # OMEGA's: plain, then three points x 4 x 10 x 2
    assert len(plain) == 120 and len(at) == 120 + 3 * 80
    assert all(s.omega == 2000.0 for s in seeds[len(at):])  # the branch never reaches 2000
    expected = [x[1] + (OMEGA - 950.0) / 50.0 * (x[2] - x[1]), x[4], x[5] + (OMEGA - 940.0) / 40.0 * (x[6] - x[5])]
    shapes = {s.origin: s.x for s in plain}
    for i, base in enumerate(expected):
        for sd in at[120 + 80 * i: 120 + 80 * (i + 1)]:
            head, on = sd.origin.split(" + ")
            assert on == f"primary DLFT NFRC {i + 1}/3" and head.split()[-1] in ("A=0.001", "A=0.002")
            own = modal_seeds(res, rom, IsolaOptions(amplitudes=(float(head.split("A=")[1]),)),
                              np.array([OMEGA]))
            shape = next(s.x for s in own if s.origin == head)
            np.testing.assert_allclose(sd.x, base + shape, rtol=0, atol=1e-15)
    assert [s.origin for s in at[:120]] == list(shapes)
    assert not modal_seeds(res, rom, IsolaOptions(primary_amplitudes=()), np.array([OMEGA]), around=(branch,))[120:]


@pytest.mark.parametrize("nu, n_harmonics, count", [(1, 40, 6560), (2, 12, 3936), (2, 40, 6560)])
def test_the_stage_estimate_counts_the_modal_seeds(nu, n_harmonics, count):
    from pipelines.stages.isolas import _estimate

    # 4 modes x (harmonics k of Omega with k nu <= N_h) x (3 amplitudes + 1 around one primary
    # point) x 41 speeds
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
