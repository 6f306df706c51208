"""The condensation on the boundary dof (hbm.harmonic.condensation) against dense and exact
rational Schur complements of the coarse rotor 67 ROM, the report of a start point that no
strategy reaches (hbm.harmonic.start), and one structured solver (hbm.harmonic.solver) for
residuals of two resolutions."""
from dataclasses import replace
from fractions import Fraction

import numpy as np
import pytest
import scipy.linalg as sla

import test_start as ts
from hbm.harmonic.condensation import CondensedModel, HarmonicForcing
from hbm.harmonic.fourier import FourierBasis
from hbm.harmonic.nfrc import default_continuation
from hbm.harmonic.start import solve_start
from hbm.linalg.dense import DirectSolver
from hbm.linalg.errors import SingularMatrixError
from support import coarse_rom

N_H = 8  # 8 x 2000 rad/s passes the first fixed-interface eigenfrequency, 13536 rad/s


def _split(rom):
    nl = np.asarray(rom.nonlinear_dofs)
    return nl, np.setdiff1d(np.arange(rom.K.shape[0]), nl)


def _schur(Z, nl, li):
    """Z_nn - Z_nl Z_ll^-1 Z_ln, dense."""
    return Z[np.ix_(nl, nl)] - Z[np.ix_(nl, li)] @ np.linalg.solve(Z[np.ix_(li, li)], Z[np.ix_(li, nl)])


def _coupled_force(Z, f, nl, li):
    """Z_nl Z_ll^-1 f_l, dense."""
    return Z[np.ix_(nl, li)] @ np.linalg.solve(Z[np.ix_(li, li)], f[li])


@pytest.mark.parametrize("harmonic", [0, 1, N_H])
def test_condensed_stiffness_force_and_recovery_match_dense_solves(harmonic):
    """Z_r,k for k = 0 .. N_h (damped ROM), the condensed force of a harmonic-k load and the
    recovered linear dof, against the dense Schur complement and a dense solve of the full
    harmonic system, at 0, 400 and 2000 rad/s (measured: 1e-16 to 1e-18 relative)."""
    rom = coarse_rom()
    K, M, C = rom.K, rom.M, rom.C
    nl, li = _split(rom)
    rng = np.random.default_rng(3)
    fc, fs = rng.standard_normal(len(K)), rng.standard_normal(len(K))
    model = CondensedModel(K, M, C, nl, FourierBasis(N_H, 32), HarmonicForcing(fc, harmonic, fs))
    f = fc - 1j * fs if harmonic else fc.astype(complex)
    for w in (0.0, 400.0, 2000.0):
        op = model.operator(w)
        xr = rng.standard_normal((2 * N_H + 1, len(nl)))
        full = model.recover(xr, w)
        for k in range(N_H + 1):
            Z = K - (k * w) ** 2 * M + 1j * k * w * C
            S = _schur(Z, nl, li)
            got = op.Z0 if k == 0 else op.P[k - 1] + 1j * op.Q[k - 1]
            assert np.abs(got - S).max() <= 1e-12 * np.abs(S).max()
            fk = f if k == harmonic else np.zeros(len(K))
            xn = xr[0] if k == 0 else xr[2 * k - 1] - 1j * xr[2 * k]
            xl = np.linalg.solve(Z[np.ix_(li, li)], fk[li] - Z[np.ix_(li, nl)] @ xn)
            rec = full[0, li] if k == 0 else full[2 * k - 1, li] - 1j * full[2 * k, li]
            np.testing.assert_allclose(rec, xl, rtol=0, atol=1e-12 * np.abs(xl).max())
        k = harmonic
        fr = f[nl] - _coupled_force(K - (k * w) ** 2 * M + 1j * k * w * C, f, nl, li)
        got = op.force[0] if k == 0 else op.force[2 * k - 1] - 1j * op.force[2 * k]
        np.testing.assert_allclose(got, fr.real if k == 0 else fr, rtol=0, atol=1e-12 * np.abs(fr).max())


def _exact_schur_columns(K, M, w, nl, li, cols):
    """Columns cols of Z_r of the undamped ROM at omega = w, rad/s, in exact rational
    arithmetic (K, M and w taken as exact): (n_r, len(cols))."""
    w2 = Fraction(w) ** 2
    Z = lambda i, j: Fraction(K[i, j]) - w2 * Fraction(M[i, j])  # noqa: E731
    out = np.empty((len(nl), len(cols)))
    for c, j in enumerate(cols):
        n = nl[j]
        A = [[Z(a, b) for b in li] + [Z(a, n)] for a in li]  # [Z_ll | Z_ln e_j], Gauss-Jordan
        for p in range(len(li)):
            piv = next(r for r in range(p, len(li)) if A[r][p] != 0)
            A[p], A[piv] = A[piv], A[p]
            A[p] = [v / A[p][p] for v in A[p]]
            for r in range(len(li)):
                if r != p and A[r][p] != 0:
                    A[r] = [v - A[r][p] * q for v, q in zip(A[r], A[p])]
        y = [row[-1] for row in A]
        out[:, c] = [float(Z(i, n) - sum(Z(i, b) * v for b, v in zip(li, y))) for i in nl]
    return out


def test_condensation_near_a_fixed_interface_eigenfrequency_is_accurate_or_refused():
    """Undamped ROM, harmonic 2 near the first fixed-interface eigenfrequency omega_fi
    (13536 rad/s, a pole of Z_r): 1e-7 off it Z_r,2 is still accurate (against the exact
    rational Schur complement: 3e-10 relative, where cond(Z_ll) = 8e7); on it (cond 2e24,
    float64 gives Z_r with relative error 1e7) it is refused, naming the harmonic."""
    rom = coarse_rom()
    K, M = rom.K, rom.M
    nl, li = _split(rom)
    w_fi = np.sqrt(sla.eigh(K[np.ix_(li, li)], M[np.ix_(li, li)], eigvals_only=True)[0])
    model = CondensedModel(K, M, np.zeros_like(K), nl, FourierBasis(3, 16))
    w = float(w_fi * (1 + 1e-7)) / 2
    cols = [0, 13, 26]
    S = _exact_schur_columns(K, M, 2 * w, nl, li, cols)
    assert np.abs(model.operator(w).P[1][:, cols] - S).max() <= 1e-8 * np.abs(S).max()
    with pytest.raises(SingularMatrixError, match=r"harmonic 2 \(k omega = 13536"):
        model.operator(float(w_fi) / 2)
    with pytest.raises(SingularMatrixError, match="harmonic 2"):
        model.recover(np.zeros((7, len(nl))), float(w_fi) / 2)


def test_a_start_no_strategy_reaches_gives_each_reason():
    """RL on the 1-dof oscillator and lobe of test_start with a residual tolerance no
    iterate can meet: every strategy fails, and the note says why for each one."""
    res = ts._residual("rl", 1e3, ts._lobe)
    opts = default_continuation(ts.HBM)
    opts = replace(opts, newton=replace(opts.newton, tol_residual=1e-300))
    _, note = solve_start(res, ts.t.W, opts, DirectSolver())
    assert note.startswith("no start found: damped Newton from the contact-free solution: no convergence"), note
    assert "; DLFT solution: no convergence" in note and "; obstacle homotopy: " in note, note
    # the homotopy's parameter is the obstacle scale s in [0, 1], not a speed
    homotopy = note.split("; obstacle homotopy: ")[1]
    assert "omega=" not in homotopy and "s=" in homotopy, note


def test_one_structured_solver_serves_residuals_of_two_resolutions():
    """An HbmSolver whose kept preconditioner is fresh (built for N_h = 3, no friction: J's
    exact inverse) then given the Jacobian of an N_h = 6 residual: it builds a new one and
    the solve meets a dense solve of that J (it used to apply the N_h = 3 preconditioner
    and fail on the shapes)."""
    from hbm.harmonic.residual import build_residual
    from hbm.harmonic.solver import HbmSolver
    from hbm.options import CasingOptions, ContactOptions, HbmOptions

    rom, solver = coarse_rom(), HbmSolver()
    for n_h in (3, 6):
        res = build_residual(rom, CasingOptions(), ContactOptions(mu=0.0), HbmOptions(n_harmonics=n_h, n_time=32),
                             method="rl")
        u = res.linear_solution(1500.0)
        u.reshape(res.n_c, res.n_r)[0, 0::3] += 1.2  # the mean radial motion into the casing: contact
        R, J, _ = res(u, 1500.0)
        assert len(J.nodes)
        x = solver.factorize(J).solve(R)
        xd = np.linalg.solve(np.asarray(J), R)
        assert np.linalg.norm(x - xd) <= 1e-10 * np.linalg.norm(xd)
