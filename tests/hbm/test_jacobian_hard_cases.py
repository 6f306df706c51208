"""The HBM Jacobians, the condensation and the contact preconditioner on the hard cases
that tests/hbm/test_jacobians.py and test_structured_jacobian.py leave out, on the coarse
rotor 67 ROM: subharmonic bases (nu = 2, 3) with friction in both senses of rotation, N_h
= 1 and 2 with N_t odd, short (at or near 2 N_h + 1) or not a power of two (the aliased
branch of FourierBasis.weighted_product), no node in contact and every node in contact
on every sample; the preconditioner against a dense solve of the matrix its docstring says
it inverts (J with the sliding terms' time means), with friction; and the condensed
residual against the uncondensed harmonic balance of the whole ROM, with a forcing in a
subharmonic basis.

References are independent of the code under test: central finite differences of the
residual, numpy's dense solves, and the full ROM's Z_k = K - (k w)^2 M + i k w C.
"""
import dataclasses

import numpy as np
import pytest

from hbm.harmonic.condensation import HarmonicForcing
from hbm.harmonic.content import harmonic_contributions
from hbm.harmonic.fourier import FourierBasis
from hbm.harmonic.preconditioner import ContactPreconditioner
from hbm.harmonic.residual import build_residual
from hbm.options import CasingOptions, ContactOptions, HbmOptions
from support import coarse_rom

OMEGA = 1500.0  # rad/s, between the 1B resonance's harmonics on the coarse ROM: Z_r regular


@pytest.fixture(scope="module")
def rom():
    return coarse_rom()


def _residual(rom, method, mu, nh, nt, nu=1, rotation=1, lanczos=True, forcing=None):
    return build_residual(dataclasses.replace(rom, rotation=rotation), CasingOptions(),
                          ContactOptions(mu=mu, lanczos=lanczos),
                          HbmOptions(n_harmonics=nh, n_time=nt, subharmonic=nu), method=method, forcing=forcing)


def _mixed_state(res, seed=1):
    """Random harmonics (u ~ 0.5, all harmonics, odd ones too for nu > 1) with the radial
    means pushed towards the casing: each node in contact on part of the period."""
    u = res.linear_solution(OMEGA) + 0.5 * np.random.default_rng(seed).standard_normal(res.size)
    u.reshape(res.n_c, res.n_r)[0, 0::3] += 0.3
    return u


def _static_state(res, inside: bool, seed=2):
    """A state with every node in contact on every sample (inside) or none on any, for DLFT
    and RL alike: radial means beyond the casing's farthest point (gap > 0) or short of its
    nearest (gap < 0), and tangential means that set the static (Z_r x)_r to -/+ 1e4 N, so
    that DLFT's prediction (f - Z_r x)_r + eps gap has the same sign; plus small harmonics."""
    op = res.model.operator(res.fundamental(OMEGA))
    r = np.arange(0, res.n_r, 3)
    t = np.setdiff1d(np.arange(res.n_r), r)
    d, c = res.distance, res.casing.clearance
    xr = np.zeros((res.n_c, res.n_r))
    xr[0, r] = d.max() + 0.5 * c if inside else d.min() - 0.5 * c
    target = (-1e4 if inside else 1e4) - op.Z0[np.ix_(r, r)] @ xr[0, r]
    xr[0, t] = np.linalg.lstsq(op.Z0[np.ix_(r, t)], target, rcond=None)[0]
    return res.to_unknowns(xr) + 0.01 * np.random.default_rng(seed).standard_normal(res.size)


def _finite_differences(res, u, omega, h=1e-6, h_omega=0.05):
    """Central differences: dR/du column by column (n_u, n_u), and dR/dOmega (n_u,). h_omega
    is large for a speed of ~1e3 rad/s: dR/dOmega is ~1e-8 of R in the contact states, so a
    smaller step leaves round-off; the truncation error stays ~(h_omega / Omega)^2."""
    n = res.size
    J = np.empty((n, n))
    for i in range(n):
        e = np.zeros(n)
        e[i] = h
        J[:, i] = (res(u + e, omega, jacobian=False) - res(u - e, omega, jacobian=False)) / (2 * h)
    dw = (res(u, omega + h_omega, jacobian=False) - res(u, omega - h_omega, jacobian=False)) / (2 * h_omega)
    return J, dw


# (method, mu, N_h, N_t, nu, rotation): N_t = 4 and 7 are 2 N_h + 2 and 2 N_h + 3 (products
# of harmonics alias: weighted_product's full-FFT branch), 30 and 27 are not powers of two
CASES = [("dlft", 0.15, 1, 4, 1, 1), ("rl", 0.15, 1, 4, 1, -1), ("dlft", 0.0, 2, 7, 1, -1),
         ("rl", 0.15, 2, 7, 1, 1), ("dlft", 0.15, 3, 30, 2, -1), ("rl", 0.15, 3, 30, 2, 1),
         ("dlft", 0.15, 3, 27, 3, -1), ("rl", 0.15, 3, 27, 3, -1), ("rl", 0.0, 3, 27, 3, 1)]


@pytest.mark.parametrize("state", ["mixed", "none", "all"])
@pytest.mark.parametrize("method,mu,nh,nt,nu,rotation", CASES)
def test_jacobians_match_finite_differences_on_hard_cases(rom, method, mu, nh, nt, nu, rotation, state):
    res = _residual(rom, method, mu, nh, nt, nu, rotation)
    u = _mixed_state(res) if state == "mixed" else _static_state(res, inside=state == "all")
    active = res.samples(res.to_coefficients(u), OMEGA).active
    if state == "mixed":
        assert 0.05 < active.mean() < 0.95
    else:
        assert active.all() if state == "all" else not active.any()
    R, Js, dw = res(u, OMEGA)
    if state == "none" and method == "dlft":
        assert len(Js.nodes) == 0  # no contact: J is Z_r alone
    J = np.asarray(Js)
    Jfd, dwfd = _finite_differences(res, u, OMEGA)
    # smooth pieces (no sample within a step of a switch): central differences err by
    # ~1e-10 relative (measured <= 1e-8 over these cases)
    assert np.abs(J - Jfd).max() <= 1e-6 * np.abs(J).max()
    assert np.abs(dw - dwfd).max() <= 1e-5 * np.abs(dwfd).max()
    V = np.random.default_rng(4).standard_normal((res.size, 3))
    assert np.abs(Js @ V - J @ V).max() <= 1e-12 * np.abs(J @ V).max()  # the FFT product
    Vc = V[:, :2] + 1j * V[:, 1:]  # complex vectors (eigenvectors): the imaginary part kept
    assert np.abs(Js @ Vc - J @ Vc).max() <= 1e-12 * np.abs(J @ Vc).max()


@pytest.mark.parametrize("method,lanczos,nu,rotation", [("dlft", True, 1, 1), ("dlft", True, 3, -1),
                                                        ("rl", True, 1, 1), ("rl", True, 3, -1),
                                                        ("rl", False, 2, 1)])
def test_preconditioner_inverts_j_with_mean_sliding_terms(rom, method, lanczos, nu, rotation):
    """ContactPreconditioner's docstring: a direct solve of J0 = J with the sliding weights
    replaced by their time means. Against a dense solve of J0 built by HbmJacobian itself
    (another code path: toarray's dense AFT products), with friction, in double precision.
    DLFT's g = eps x_r - (Z_r x)_r with the mean friction in Z_r' only, RL's Lanczos factors."""
    res = _residual(rom, method, 0.15, 3, 32 if nu == 1 else 27, nu, rotation, lanczos)
    R, J, _ = res(_mixed_state(res), OMEGA)
    assert J.friction and len(J.nodes) >= 5
    w = J.weights.copy()
    w[:, 3:] = w[:, 3:].mean(axis=-1, keepdims=True)
    J0 = np.asarray(dataclasses.replace(J, weights=w))
    b = np.random.default_rng(1).standard_normal(res.size)
    x = ContactPreconditioner(J, single=False)(b)
    x0 = np.linalg.solve(J0, b)
    # rounding times cond(J0) ~ 1e5: measured 1e-13
    assert np.linalg.norm(x - x0) <= 1e-10 * np.linalg.norm(x0)
    # the fluctuating sliding terms matter here: J's own solution is another one
    assert np.linalg.norm(x - np.linalg.solve(np.asarray(J), b)) > 1e-4 * np.linalg.norm(x0)


@pytest.mark.parametrize("nu", [2, 3])
@pytest.mark.parametrize("harmonic", [0, 1, 2])
@pytest.mark.parametrize("method", ["dlft", "rl"])
def test_condensed_residual_is_the_full_rom_harmonic_balance(rom, method, harmonic, nu):
    """In the basis of Omega / nu a forcing on harmonic k of Omega is basis harmonic k nu, and
    the ROM's harmonic k' blocks are Z at k' Omega / nu. Checked against the uncondensed
    equations of all n ROM dof: the linear forced response solved on the full ROM equals
    linear_solution's (recovered); at a state in contact, the recovered harmonics satisfy the
    linear dof's rows, and the boundary rows equal the condensed residual H_r."""
    K, M, C = rom.K, rom.M, rom.C
    n, nr = K.shape[0], 3 * rom.n_boundary
    rng = np.random.default_rng(5)
    fc, fs = 10.0 * rng.standard_normal(n), 10.0 * rng.standard_normal(n)  # boundary and modal dof
    forcing = HarmonicForcing(fc, harmonic, fs if harmonic else None)
    res = _residual(rom, method, 0.15, 3 * nu, 8 * nu + 3, nu, forcing=forcing)
    w, kb, nc = OMEGA / nu, harmonic * nu, res.n_c

    def blocks(k):
        return K - (k * w) ** 2 * M + 1j * k * w * C

    F = np.zeros((nc, n))
    if kb == 0:
        F[0] = fc
    else:
        F[2 * kb - 1], F[2 * kb] = fc, fs
    X = np.zeros((nc, n))
    if kb == 0:
        X[0] = np.linalg.solve(K, fc)
    else:
        Y = np.linalg.solve(blocks(kb), fc - 1j * fs)
        X[2 * kb - 1], X[2 * kb] = Y.real, -Y.imag
    lin = res.expand_harmonics(res.linear_solution(OMEGA), OMEGA)
    assert np.abs(lin - X).max() <= 1e-10 * np.abs(X).max()  # measured 5e-13 (cond of Z)

    u = res.linear_solution(OMEGA) + 0.5 * rng.standard_normal(res.size)
    u.reshape(nc, nr)[0, 0::3] += 0.3
    smp = res.samples(res.to_coefficients(u), OMEGA)
    assert 0.05 < smp.active.mean() < 0.95
    full = res.expand_harmonics(u, OMEGA)
    H = np.zeros((nc, n))
    H[0] = K @ full[0]
    for k in range(1, res.basis.n_harmonics + 1):
        Y = blocks(k) @ (full[2 * k - 1] - 1j * full[2 * k])
        H[2 * k - 1], H[2 * k] = Y.real, -Y.imag
    H[:, :nr] += res.sigma[:, None] * res.basis.to_freq(smp.force.reshape(-1, nr))
    H -= F
    Hr = res(u, OMEGA, jacobian=False).reshape(nc, nr) * res.k_ref / res.alpha
    scale = np.abs(H[:, :nr]).max()
    assert np.abs(H[:, nr:]).max() <= 1e-12 * scale  # measured 1e-17
    assert np.abs(H[:, :nr] - Hr).max() <= 1e-12 * scale  # measured 1e-15


@pytest.mark.parametrize("nh", [1, 2, 5])
def test_fourier_conventions_at_the_shortest_grid(nh):
    """eq. (2)/(5) order and the factor on harmonic 0 at the shortest grid N_t = 2 N_h + 1
    (odd: no Nyquist bin, every harmonic has its sine), the AFT products there (orders up to
    2 N_h alias), eq. (34) amplitudes, and N_t = 2 N_h refused by name (the Nyquist bin N_h
    would lose b_Nh)."""
    b = FourierBasis(nh, 2 * nh + 1)
    c = np.random.default_rng(0).standard_normal(b.n_coeffs)
    tau = b.tau
    x = c[0] + sum(c[2 * k - 1] * np.cos(k * tau) + c[2 * k] * np.sin(k * tau) for k in range(1, nh + 1))
    assert np.abs(b.to_time(c) - x).max() <= 1e-13
    assert np.abs(b.to_freq(x) - c).max() <= 1e-13  # exact interpolation: the mean is c_0, not a_0
    assert np.isclose(b.to_freq(x)[0], x.mean())
    amp = harmonic_contributions(c)
    assert np.allclose(amp, [abs(c[0])] + [np.hypot(c[2 * k - 1], c[2 * k]) for k in range(1, nh + 1)])
    w = np.random.default_rng(1).random(b.n_time)
    Fm, Ft = b.to_freq(np.eye(b.n_time)), b.to_time(np.eye(b.n_coeffs))
    assert np.abs(b.weighted_product(w) - Fm @ np.diag(w) @ Ft).max() <= 1e-13
    with pytest.raises(ValueError, match=rf"n_time = {2 * nh} too small for {nh} harmonics"):
        FourierBasis(nh, 2 * nh)


def test_forcing_harmonic_and_amplitudes_are_checked_by_name(rom):
    """A forcing on harmonic 1.5, True or -1, or with amplitudes not on the n ROM dof, is
    refused naming the field (they used to fail deep in the condensation with numpy's
    IndexError); an integral float 2.0 is harmonic 2."""
    n = rom.n_dof
    for bad in (1.5, True, -1, "2"):
        with pytest.raises(ValueError, match="forcing harmonic must be an integer >= 0"):
            HarmonicForcing(np.ones(n), bad)
    opts = HbmOptions(n_harmonics=3, n_time=16)
    for kw, name in ((dict(cos_amplitude=np.ones(3 * rom.n_boundary)), "cos_amplitude"),
                     (dict(cos_amplitude=np.ones(n), sin_amplitude=np.ones((n, 1))), "sin_amplitude")):
        with pytest.raises(ValueError, match=rf"forcing {name} must have shape \({n},\)"):
            build_residual(rom, CasingOptions(), ContactOptions(), opts, forcing=HarmonicForcing(harmonic=1, **kw))
    f = np.random.default_rng(0).standard_normal(n)
    u = [build_residual(rom, CasingOptions(), ContactOptions(), opts,
                        forcing=HarmonicForcing(f, k)).linear_solution(OMEGA) for k in (2, 2.0, np.int64(2))]
    assert HarmonicForcing(f, 2.0).harmonic == 2 and type(HarmonicForcing(f, np.int64(2)).harmonic) is int
    assert np.abs(u[1] - u[0]).max() == 0.0 and np.abs(u[2] - u[0]).max() == 0.0
    assert np.abs(u[0]).max() > 0.0


def test_a_forcing_beyond_a_subharmonic_basis_is_named_as_written(rom):
    """In the basis Omega/2 the forcing's harmonic 2 of Omega is the basis' harmonic 4: with
    N_h = 3 the error names the harmonic the caller wrote, and the basis' one."""
    opts = HbmOptions(n_harmonics=3, n_time=16, subharmonic=2)
    with pytest.raises(ValueError, match=r"forcing harmonic 2 of Omega is harmonic 4 of the basis Omega/2"):
        build_residual(rom, CasingOptions(), ContactOptions(), opts,
                       forcing=HarmonicForcing(np.ones(rom.n_dof), 2))
    build_residual(rom, CasingOptions(), ContactOptions(), dataclasses.replace(opts, n_harmonics=4),
                   forcing=HarmonicForcing(np.ones(rom.n_dof), 2))
