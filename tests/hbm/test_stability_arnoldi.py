"""The fast Floquet spectrum (shift-invert Arnoldi with H(0)^-1 from the condensation on the
dof in contact, hbm.stability.hill.HillSolver, and the fused pencil product HillOperator.tail)
against the eigenvalues of the whole linearised Hill pencil by dense QZ (HillOperator.dense,
assembled by Kronecker products: another code path, and another eigensolver).

Rotor 67 coarse ROM, N_h = 12, N_t = 256 (T / 2-periodic orbits: Hill's problem in the
2 Omega basis, 13 x 39 unknowns, a 1014-square pencil for QZ), DLFT and RL, at points of a
short NFRC near the 2B x 4 Omega resonance where some but not all of the 9 boundary nodes
touch the casing (DLFT: 6 to 8 nodes; so that the boundary dof out of contact are eliminated
with the modal ones).

At so few harmonics most of ARPACK's 40 eigenvalues are off-centre family members (truncated:
their multipliers are not the centred member's, and the verdicts of the two spectra can
differ, which is why the product runs N_h = 40); the centred ones are eigenvalues of the
same truncated pencil in both, which is what is compared.
"""

import numpy as np
import pytest

from hbm.harmonic.nfrc import compute_nfrc
from hbm.harmonic.residual import build_residual
from hbm.options import CasingOptions, ContactOptions, HbmOptions
from hbm.stability.hill import HillOperator, HillSolver, harmonic_period, restrict
import scipy.linalg as sla

from hbm.stability.spectrum import arnoldi_spectrum
from support import coarse_rom

OPTS = HbmOptions(n_harmonics=12, n_time=256, omega_min=1940.0, omega_max=2000.0)


@pytest.fixture(scope="module", params=["dlft", "rl"])
def operators(request):
    rom = coarse_rom()
    r = compute_nfrc(rom, CasingOptions(), ContactOptions(), OPTS, request.param, stability=False)
    res = build_residual(rom, CasingOptions(), ContactOptions(), OPTS, method=request.param)
    out = []
    for i in (len(r.omega) // 2,):  # one point: QZ of the 1014-square pencil takes ~10 s
        u, w = r.unknowns[i], float(r.omega[i])
        H = HillOperator.from_residual(res, u, w)
        out.append((w, restrict(H, harmonic_period(res.to_coefficients(u), 1e-4))))
    if request.param == "dlft":  # the case this test is for: nodes out of contact eliminated too
        assert all(0 < len(H.nodes) < 9 for _, H in out), [len(H.nodes) for _, H in out]
    return out


def test_solver_inverts_the_hill_operator_at_zero(operators):
    # H(0) H(0)^-1 b = b with H(0) applied by HillOperator.terms (all dof, no condensation):
    # round-off of a dense LU of a matrix with condition ~1e6-1e8, measured 1e-13 to 1e-12
    rng = np.random.default_rng(1)
    for w, H in operators:
        S = HillSolver(H)
        for b in (rng.standard_normal(H.size), rng.standard_normal(H.size) + 1j * rng.standard_normal(H.size)):
            back, = H.terms(S(b), (0,))
            assert np.linalg.norm(back - b) <= 1e-9 * np.linalg.norm(b), w


def test_compiled_pencil_tail_is_the_kronecker_assembly(operators):
    # L1 p1 + L2 p2 by the compiled contact products (hbm.stability.kernels) against the
    # pencil assembled by Kronecker products and dense AFT blocks (HillOperator.dense), real
    # and complex coefficients: round-off, measured 1e-16 to 1e-15 of the norm
    rng = np.random.default_rng(2)
    for w, H in operators:
        _, L1, L2 = H.dense()
        for p1, p2 in ((rng.standard_normal(H.size), rng.standard_normal(H.size)),
                       (rng.standard_normal(H.size) + 1j * rng.standard_normal(H.size), rng.standard_normal(H.size))):
            ref = L1 @ p1 + L2 @ p2
            assert np.linalg.norm(H.tail(p1, p2) - ref) <= 1e-12 * np.linalg.norm(ref), w


def test_arnoldi_exponents_are_the_dense_pencils(operators):
    for w, H in operators:
        L0, L1, L2 = H.dense()
        n = H.size
        I, Z = np.eye(n), np.zeros((n, n))
        lam_all = sla.eigvals(np.block([[Z, I], [-L0, -L1]]), np.block([[I, Z], [Z, L2]]))
        lam_all = lam_all[np.isfinite(lam_all)]
        fast = arnoldi_spectrum(H)
        assert not fast.note, (w, fast.note)
        centred = fast.exponents[fast.centred]
        assert len(centred) >= 2, (w, fast.exponents)
        # a centred member is its own representative (no shift): an eigenvalue of the pencil.
        # The same eigenvalue from ARPACK (tol 1e-9 on 1 / lam) and from QZ: measured agreement
        # 8e-8 to 4e-7 of |lam| (QZ's backward error times the pencil's condition); 1e-5 |lam|
        # (at most 1e-5 |lam| T ~ 3e-5 in log|mu| here) still tells apart the eigenvalues of
        # different families, which lie omega / 100 apart or more
        for lam in centred:
            gap = np.min(np.abs(lam_all - lam))
            assert gap <= 1e-5 * abs(lam), (w, lam, gap)


def test_a_family_member_shifted_by_m_harmonics_is_p_times_exp_minus_i_m_omega_t():
    """shift_member on p(t) = cos t (N = 2): one harmonic gives cos t e^{-i t} = (1 + e^{-2it}) / 2,
    two give the e^{-3it} part cut off by the band, and a shift past the whole band (an
    Arnoldi pair m omega apart with m > 2 N, met at N_h = 5) gives zeros rather than an error."""
    from hbm.stability.spectrum import shift_member

    P = np.zeros((5, 1))
    P[1, 0] = 1.0  # the cos t coefficient, eq. (5) order [P_0, a_1, b_1, a_2, b_2]
    np.testing.assert_allclose(shift_member(P, 1)[:, 0], [0.5, 0, 0, 0.5, -0.5j], atol=1e-15)
    t = np.linspace(0, 2 * np.pi, 7)
    q = shift_member(P, 2)[:, 0]  # cos t e^{-2it} = (e^{-it} + e^{-3it}) / 2: e^{-3it} is out of the band
    p = q[0] + q[1] * np.cos(t) + q[2] * np.sin(t) + q[3] * np.cos(2 * t) + q[4] * np.sin(2 * t)
    np.testing.assert_allclose(p, 0.5 * np.exp(-1j * t), atol=1e-15)
    for m in (5, 7, -5, -9):
        assert not np.any(shift_member(P, m))
