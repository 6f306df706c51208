"""Compiled products of Hill's shift-invert step (numba), on real coefficient arrays.

Shift-invert Arnoldi applies H(0)^-1 (L1 z1 + L2 z2) about a hundred times per Floquet
analysis (hbm.stability.spectrum.arnoldi_spectrum); apart from the dense LU solve on the
dof in contact, each application is a dozen products of small blocks: per-harmonic
eliminations of the linear dof, their coupling to the contact dof, and the contact's AFT
products T (n_c, n_c) per node. As numpy calls they took as long as the LU solve itself
(the blocks are 41 x 18 to 41 x 41 at N_h = 40 in the T / 2 basis: call overhead, not
arithmetic).

Coefficient arrays follow eq. (5): rows [c_0, a_1, b_1, ..., a_N, b_N], one column per dof.
Every product is a dot product of contiguous rows in the helper `_dot`: written as nested
`range` loops in one function, numba's loop lowering kept LLVM from vectorising the inner
loop (scalar FMAs, 3.5 times slower on a 41-square block).
"""
from __future__ import annotations

import numpy as np
from numba import njit

# reassociation lets the dot products vectorise; contraction gives FMAs. The results differ
# from numpy's at round-off only.
_FAST = {"reassoc", "contract"}


@njit(cache=True, fastmath=_FAST, _nrt=False)
def _dot(a, b):
    """sum_k a[k] b[k] over two contiguous 1-D arrays of equal length."""
    acc = 0.0
    for k in range(a.shape[0]):
        acc += a[k] * b[k]
    return acc


@njit(cache=True, fastmath=_FAST)
def harmonic_blocks(X, A0, AR, AI, out):
    """out = the harmonic-by-harmonic block product of real coefficients X (n_c, m),
    contiguous rows: out_0 = A0 X_0 and per harmonic k, as columns,
    out_(a_k) = AR_k X_(a_k) + AI_k X_(b_k), out_(b_k) = AR_k X_(b_k) - AI_k X_(a_k).
    A0 (p, m), AR and AI (N_h, p, m); out: (n_c, p), written; returned.

    Two uses. Solve: A0, AR, AI the inverse of the static block and the real and imaginary
    parts of the inverses of Z_k = K - (k w)^2 M + i k w C (in complex form the pair
    (a_k, b_k) is c = a - i b, and Z_k^-1 c = y gives a' = Re y, b' = -Im y). Couple:
    X K^T + w (D X) C^T + w^2 (D^2 X) M^T from one dof set to another, with A0 = K,
    AR_k = K - (k w)^2 M, AI_k = k w C ((D X)_(a_k) = k X_(b_k), (D X)_(b_k) = -k X_(a_k)).
    """
    p = A0.shape[0]
    x0 = X[0]
    for j in range(p):
        out[0, j] = _dot(A0[j], x0)
    for k in range(AR.shape[0]):
        xa = X[2 * k + 1]
        xb = X[2 * k + 2]
        rr = AR[k]
        ii = AI[k]
        for j in range(p):
            out[2 * k + 1, j] = _dot(rr[j], xa) + _dot(ii[j], xb)
            out[2 * k + 2, j] = _dot(rr[j], xb) - _dot(ii[j], xa)
    return out


@njit(cache=True, fastmath=_FAST)
def add_normal(Y, gT, T, rows, nq):
    """Y[:, rows[i] + q] += T[i, q] gT[i] for every node i and q < nq: the normal force's
    channels (radial, and with friction theta and z) driven by the contact signal g.

    Y: (n_c, n) coefficients, updated. gT: (n_t, n_c) the signal of each node. T:
    (n_t, n_w, n_c, n_c) the AFT products. rows: (n_t,) the column of each node's radial
    dof in Y.
    """
    nc = Y.shape[0]
    for i in range(rows.shape[0]):
        g = gT[i]
        for q in range(nq):
            Ti = T[i, q]
            c = rows[i] + q
            for a in range(nc):
                Y[a, c] += _dot(Ti[a], g)


@njit(cache=True, fastmath=_FAST)
def add_sliding(Y, V, T, rows):
    """Y's theta and z columns of each node += the friction's sliding terms of the velocity
    coefficients V (n_c, n): [T3 T4; T4 T5] applied to (v_theta, v_z) of node i, channels
    3, 4, 5 of the AFT products T (n_t, 6, n_c, n_c). rows: (n_t,) each node's radial column."""
    nc = Y.shape[0]
    vt = np.empty(nc)
    vz = np.empty(nc)
    for i in range(rows.shape[0]):
        t = rows[i] + 1
        z = rows[i] + 2
        for b in range(nc):  # gathered once: the dot products then run over contiguous rows
            vt[b] = V[b, t]
            vz[b] = V[b, z]
        T3 = T[i, 3]
        T4 = T[i, 4]
        T5 = T[i, 5]
        for a in range(nc):
            Y[a, t] += _dot(T3[a], vt) + _dot(T4[a], vz)
            Y[a, z] += _dot(T4[a], vt) + _dot(T5[a], vz)


@njit(cache=True, fastmath=_FAST)
def condensed_rhs(B, nl, li, Z0, ZR, ZI, A0, AK, AC, T, rows, nq, g_z, Bl, Y, C, gT, rhs):
    """The right-hand side of the condensed solve of H(0) x = B (hbm.stability.hill.HillSolver):
    y = Z_ll^-1 B_l on the linear dof li, rhs = B_n - H_nl y on the dof in contact nl, with
    H_nl y = the linear coupling (A0, AK, AC: harmonic_blocks' coupling blocks from li to
    nl) and, for DLFT (g_z != 0), the contact's g = -g_z (H_lin y)_r on the radial rows `rows` of nl
    (T: the AFT products, nq normal channels, as add_normal).

    B: (n_c, n) real. Work arrays, written: Bl, Y (n_c, n_l); C, rhs (n_c, n_r); gT
    (n_t, n_c). Y is the y that expand_solution needs.
    """
    nc = B.shape[0]
    for c in range(nc):
        for j in range(li.shape[0]):
            Bl[c, j] = B[c, li[j]]
    harmonic_blocks(Bl, Z0, ZR, ZI, Y)
    harmonic_blocks(Y, A0, AK, AC, C)
    if g_z != 0.0 and rows.shape[0] > 0:
        for i in range(rows.shape[0]):
            for c in range(nc):
                gT[i, c] = -g_z * C[c, rows[i]]
        add_normal(C, gT, T, rows, nq)
    for c in range(nc):
        for j in range(nl.shape[0]):
            rhs[c, j] = B[c, nl[j]] - C[c, j]


@njit(cache=True, fastmath=_FAST)
def expand_solution(xn, Y, nl, li, Z0, ZR, ZI, A0, AK, AC, back, t2, X):
    """x on all dof from the condensed solution xn (n_c, n_r) on nl: x_n = xn,
    x_l = y - Z_ll^-1 H_ln x_n (A0, AK, AC: harmonic_blocks' coupling blocks from nl to li;
    H_ln is linear, the contact acts on rows nl only). Work arrays back, t2 (n_c, n_l); X (n_c, n)
    written."""
    nc = xn.shape[0]
    harmonic_blocks(xn, A0, AK, AC, back)
    harmonic_blocks(back, Z0, ZR, ZI, t2)
    for c in range(nc):
        for j in range(nl.shape[0]):
            X[c, nl[j]] = xn[c, j]
        for j in range(li.shape[0]):
            X[c, li[j]] = Y[c, j] - t2[c, j]
