"""Compiled step loop of the central-difference march (numba): one loop, two contact schemes.

Every step m (t_m = m dt) does, in this order:
1. predict: q_hat_m = c1 q_{m-1} - c2 q_{m-2} (- s C_off v for non-modal damping) and the
   radial boundary displacements r_hat = Phi_r q_hat, in one pass over the modes;
2. (massless scheme only) apply the contact forces of step m-1 to q_m: they act on the
   modal dof one step later, as any force of central differences;
3. find the nodes beyond the casing of eq. (28) (the casing law of hbm.contact.casing,
   compiled here from its one source, or its table over one casing period) and solve the
   linear complementarity problem r = r_hat - A lam <= d, lam >= 0, lam (d - r) = 0 on the
   penetrating nodes by an active set; A = the scheme's compliance (with the friction
   columns of the sliding direction);
4. (Carpenter) apply the forward-increment multipliers to q_m: the constraint holds at m;
   with friction, the sliding direction is that of the step's own centred velocity, which
   the multipliers move: steps 3-4 are repeated until it settles (run_steps);
5. record.
The modal recurrence (c1, c2, s) is the caller's: central differences, or each mode's exact
free motion (the exponential scheme, hbm.ti.march.recurrence); the loop is the same.

Carpenter, Taylor and Katona (1991): lam_{m-1} is chosen so that r_m <= d_m; A = Phi_r S
Phi_b^T g, S = diag(dt^2 / (1 + a_k)): the impulse a step needs to stop the boundary.
Massless boundary: r_m = Phi_r q_m - G lam_m with G the residual (static) flexibility of
the boundary; lam_m is a static projection at t_m, applied to the modes at the next step.

All arrays are preallocated by the caller (hbm.ti.march); the loop allocates only its own
work arrays once per call, so a march may be run in chunks (the state is read from and
written back to `state`, and recording positions count from the global step index). The
per-node vectors are rows of one block and the n_b-square matrices slices of another: as
a dozen small allocations, wherever they fell, the same march ran up to 30 % slower from
one call to the next.

The helpers the loop calls are compiled without numba's reference counting (_nrt=False:
they only read and write the arrays they are given). With it, every array passed to a
helper costs an atomic increment and decrement at every call, inlined by numba or not:
25 to 30 % of a step on rotor 67 (perf). The loop itself keeps it: its work arrays,
allocated there, are known to LLVM not to alias anything, which keeps its loops vectorised
(allocated by the caller and passed in, the step was 10 % slower).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from hbm.contact import casing as _casing_law

# reassociation lets LLVM vectorise the modal sums; contraction allows FMAs; reciprocals
# turn the casing law's divisions by constants into products (with reassociation alone LLVM
# rewrote x * (n_l / 2 pi) as (x n_l) / 2 pi: three divisions per node and step). No other
# fast-math flag: inf and nan must keep their meaning (the diagnostics start at +-inf).
_FAST = {"reassoc", "contract", "arcp"}

#: The casing law of eq. (28), compiled from the same source as hbm.contact.casing.casing_distance.
lobe_coordinate = njit(cache=True, inline="always")(_casing_law.lobe_coordinate)
gap_at = njit(cache=True, inline="always")(_casing_law.gap_at)

#: Radial rows are padded to this many columns when n_b <= FAST_NODES (see _predict_fast).
FAST_NODES = 12

#: Carpenter's sliding direction is settled when a pass would move no node's unit direction
#: by more than this (|d s_theta| + |d s_z|): the friction force then errs by at most mu lam
#: times it, 1.5e-4 of the normal force at mu = 0.15. 1e-3, 1e-4 and 1e-5 give the same
#: rotor 67 LE amplitudes to 3e-4 (relative; 1000 and 1400 rad/s, dt = 1e-7 and 4e-7); 1e-4
#: takes 0.7 to 1 pass more per contact step than 1e-3, 1.3 to 1.4 times the march's time.
DIRECTION_TOL = 1e-3
#: The most passes of a step (solve, new direction, solve again) before it falls back to the
#: prediction's direction (run_steps). On rotor 67 at mu = 0.15 a contact step takes 1.2 to
#: 1.5 passes on average.
DIRECTION_PASSES = 8


@njit(cache=True, fastmath=_FAST, _nrt=False)
def _predict_fast(c1, c2, q, qm, qn, prT, rh):
    """q_hat = c1 q - c2 qm and rh = prT^T q_hat for n_b <= 12 (prT padded to 12 columns).

    Twelve scalar accumulators that LLVM keeps in (vector) registers; an array accumulator
    is reloaded for every mode (4-5 times slower). Two sets of them, for even and odd
    modes: with one, each vector register waits for its previous FMA at every mode (a
    chain of n FMA latencies); with two the chains are half as long and interleave (12 %
    off a step out of contact; written as range(0, n - 1, 2) the loop came out 10 % slower
    than with one set)."""
    r0 = r1 = r2 = r3 = r4 = r5 = r6 = r7 = r8 = r9 = r10 = r11 = 0.0
    u0 = u1 = u2 = u3 = u4 = u5 = u6 = u7 = u8 = u9 = u10 = u11 = 0.0
    n = c1.shape[0]
    for kk in range(n // 2):
        k = 2 * kk
        v = c1[k] * q[k] - c2[k] * qm[k]
        w = c1[k + 1] * q[k + 1] - c2[k + 1] * qm[k + 1]
        qn[k] = v
        qn[k + 1] = w
        r0 += prT[k, 0] * v
        r1 += prT[k, 1] * v
        r2 += prT[k, 2] * v
        r3 += prT[k, 3] * v
        r4 += prT[k, 4] * v
        r5 += prT[k, 5] * v
        r6 += prT[k, 6] * v
        r7 += prT[k, 7] * v
        r8 += prT[k, 8] * v
        r9 += prT[k, 9] * v
        r10 += prT[k, 10] * v
        r11 += prT[k, 11] * v
        u0 += prT[k + 1, 0] * w
        u1 += prT[k + 1, 1] * w
        u2 += prT[k + 1, 2] * w
        u3 += prT[k + 1, 3] * w
        u4 += prT[k + 1, 4] * w
        u5 += prT[k + 1, 5] * w
        u6 += prT[k + 1, 6] * w
        u7 += prT[k + 1, 7] * w
        u8 += prT[k + 1, 8] * w
        u9 += prT[k + 1, 9] * w
        u10 += prT[k + 1, 10] * w
        u11 += prT[k + 1, 11] * w
    if n % 2:
        k = n - 1
        v = c1[k] * q[k] - c2[k] * qm[k]
        qn[k] = v
        r0 += prT[k, 0] * v
        r1 += prT[k, 1] * v
        r2 += prT[k, 2] * v
        r3 += prT[k, 3] * v
        r4 += prT[k, 4] * v
        r5 += prT[k, 5] * v
        r6 += prT[k, 6] * v
        r7 += prT[k, 7] * v
        r8 += prT[k, 8] * v
        r9 += prT[k, 9] * v
        r10 += prT[k, 10] * v
        r11 += prT[k, 11] * v
    rh[0] = r0 + u0
    rh[1] = r1 + u1
    rh[2] = r2 + u2
    rh[3] = r3 + u3
    rh[4] = r4 + u4
    rh[5] = r5 + u5
    rh[6] = r6 + u6
    rh[7] = r7 + u7
    rh[8] = r8 + u8
    rh[9] = r9 + u9
    rh[10] = r10 + u10
    rh[11] = r11 + u11


@njit(cache=True, fastmath=_FAST, _nrt=False)
def _predict_general(c1, c2, s, coff, has_coff, dt, q, qm, qn, prT, rh, vel):
    """q_hat and rh for any n_b; with non-modal damping the off-diagonal part of phi^T C phi
    acts on the backward-difference velocity (lagged, explicit)."""
    n = c1.shape[0]
    nb = prT.shape[1]
    for j in range(nb):
        rh[j] = 0.0
    if has_coff:
        for k in range(n):
            vel[k] = (q[k] - qm[k]) / dt
    for k in range(n):
        v = c1[k] * q[k] - c2[k] * qm[k]
        if has_coff:
            acc = 0.0
            for l in range(n):
                acc += coff[k, l] * vel[l]
            v -= s[k] * acc
        qn[k] = v
        for j in range(nb):
            rh[j] += prT[k, j] * v


@njit(cache=True, fastmath=_FAST, _nrt=False)
def _find_penetrations(tau, theta, rh, cas, margin, fac, z, d, exact, active):
    """Mark the nodes with rh_j >= d_j(tau); return (any penetration, any node near the casing).

    z_j comes from the casing law (lobe_coordinate) for every node; the exponential (gap_at)
    only for the nodes a cheap test cannot rule out: e^{-z^2} <= 1 / fac, fac = 1 + z^2 + z^4 / 2,
    so d_j >= c - (c + p) / fac when c + p >= 0, and a node with (c - r_j) fac_j > c + p + margin
    is free (margin = 1e-12 (|c| + |p|) m: far above round-off, far below any physical gap).
    With c + p < 0 every node is evaluated. Only nodes near the casing (exact_j) get d_j; the
    others are certainly free and their d_j is stale. fac_j is kept for the same test after
    the contact correction."""
    clearance, penetration, width, n_lobes = cas
    cpp = clearance + penetration
    nb = theta.shape[0]
    near = False
    for j in range(nb):
        zj = lobe_coordinate(tau + theta[j], n_lobes, width)
        z[j] = zj
        z2 = zj * zj
        f = 1.0 + z2 * (1.0 + 0.5 * z2)
        fac[j] = f
        free = (clearance - rh[j]) * f > cpp + margin and cpp >= 0.0
        exact[j] = not free
        near = near or not free
    any_pen = False
    if near:
        for j in range(nb):
            active[j] = False
            if exact[j]:
                d[j] = gap_at(z[j], clearance, penetration)
                if rh[j] >= d[j]:
                    active[j] = True
                    any_pen = True
    return any_pen, near


@njit(cache=True, fastmath=_FAST, _nrt=False)
def _profile_penetrations(profile, k, rh, d, active):
    """Mark the nodes with rh_j >= d_j, d_j read from row k of the casing profile (see
    run_steps); return whether any node penetrates. Every d_j is exact: no bound, no
    exponential, no branch. The row is indexed here, not sliced by the caller: a slice made
    in the step loop is a new array, with numba's reference counts."""
    any_pen = False
    for j in range(d.shape[0]):
        dj = profile[k, j]
        d[j] = dj
        a = rh[j] >= dj
        active[j] = a
        any_pen = any_pen or a
    return any_pen


@njit(cache=True, fastmath=_FAST, _nrt=False)
def _node_increments(qn, qb, pt, pz, j):
    """(pt[j] . (qn - qb), pz[j] . (qn - qb)): node j's theta and z displacement increments."""
    ptj = pt[j]
    pzj = pz[j]
    a = 0.0
    b = 0.0
    for k in range(qn.shape[0]):
        dq = qn[k] - qb[k]
        a += ptj[k] * dq
        b += pzj[k] * dq
    return a, b


@njit(cache=True, fastmath=_FAST, _nrt=False)
def _solve_small(A, b, m):
    """Solve A[:m, :m] x = b[:m] in place; m > 3 by Gaussian elimination with partial pivoting.

    m <= 3 (two or three tip nodes in contact: nearly every contact step) by the adjugate
    (Cramer's rule), on scalars: one division and no branch. The unrolled elimination with
    pivoting before it had a chain of three divisions and the pivots' branches, 8 % of a
    contact-heavy march (perf; 1.5 solves per contact step); the adjugate takes 3.5 % less
    time over the whole march at 650 rad/s. For 2 and 3 unknowns its error stays within a
    few ulps times the condition number (tests/hbm/test_ti_kernel.py, against LAPACK, zero
    leading pivots included); the contact compliances it sees are diagonally dominant."""
    if m == 1:
        b[0] = b[0] / A[0, 0]
        return
    if m == 2:
        a00, a01, a10, a11, b0, b1 = A[0, 0], A[0, 1], A[1, 0], A[1, 1], b[0], b[1]
        inv = 1.0 / (a00 * a11 - a01 * a10)
        b[0] = (a11 * b0 - a01 * b1) * inv
        b[1] = (a00 * b1 - a10 * b0) * inv
        return
    if m == 3:
        a00, a01, a02, b0 = A[0, 0], A[0, 1], A[0, 2], b[0]
        a10, a11, a12, b1 = A[1, 0], A[1, 1], A[1, 2], b[1]
        a20, a21, a22, b2 = A[2, 0], A[2, 1], A[2, 2], b[2]
        c00 = a11 * a22 - a12 * a21
        c01 = a12 * a20 - a10 * a22
        c02 = a10 * a21 - a11 * a20
        inv = 1.0 / (a00 * c00 + a01 * c01 + a02 * c02)
        b[0] = (c00 * b0 + (a02 * a21 - a01 * a22) * b1 + (a01 * a12 - a02 * a11) * b2) * inv
        b[1] = (c01 * b0 + (a00 * a22 - a02 * a20) * b1 + (a02 * a10 - a00 * a12) * b2) * inv
        b[2] = (c02 * b0 + (a01 * a20 - a00 * a21) * b1 + (a00 * a11 - a01 * a10) * b2) * inv
        return
    for k in range(m):
        piv = k
        big = abs(A[k, k])
        for i in range(k + 1, m):
            if abs(A[i, k]) > big:
                big = abs(A[i, k])
                piv = i
        if piv != k:
            for j in range(m):
                tmp = A[k, j]
                A[k, j] = A[piv, j]
                A[piv, j] = tmp
            tmp = b[k]
            b[k] = b[piv]
            b[piv] = tmp
        for i in range(k + 1, m):
            f = A[i, k] / A[k, k]
            for j in range(k, m):
                A[i, j] -= f * A[k, j]
            b[i] -= f * b[k]
    for k in range(m - 1, -1, -1):
        acc = b[k]
        for j in range(k + 1, m):
            acc -= A[k, j] * b[j]
        b[k] = acc / A[k, k]


@njit(cache=True, fastmath=_FAST, _nrt=False)
def _add_row(qn, spr, spt, spz, j, fr, ft, fz):
    """qn -= spr[j] fr + spt[j] ft + spz[j] fz: node j's force (fr, ft, fz), N, moved into the
    modal update; spr, spt, spz: the radial, theta and z rows of phi scaled by the update's
    s = dt^2 / (1 + a_k), (n_b, n_pad). Written on the rows as 1-D arrays, the loop
    vectorises (with LLVM's runtime alias check); indexed pr[j, k] inside the step loop it
    did not. The rows are scaled once per call, not at every step (a product fewer per mode:
    3 % of a contact-heavy march)."""
    a = spr[j]
    b = spt[j]
    c = spz[j]
    for k in range(qn.shape[0]):
        qn[k] -= a[k] * fr + b[k] * ft + c[k] * fz


@njit(cache=True, fastmath=_FAST, _nrt=False)
def _compliance_row(AcolT, ArrT, ArtT, ArzT, j, ft, fz):
    """AcolT[j] = ArrT[j] + ft ArtT[j] + fz ArzT[j]: node j's column of the compliance with its
    friction direction (ft, fz = mu s_theta, mu s_z), stored as a row."""
    row, a, b, c = AcolT[j], ArrT[j], ArtT[j], ArzT[j]
    for i in range(row.shape[0]):
        row[i] = a[i] + (b[i] * ft + c[i] * fz)


@njit(cache=True, fastmath=_FAST, _nrt=False)
def _correct(rh, AcolT, idx, x, m, out, by_node):
    """out = rh - sum_b AcolT[idx[b]] y_b, y_b = x[idx[b]] (by_node) or x[b], on the n_b
    nodes (rh may be padded): the radial displacements after the contact forces of the m
    nodes idx[:m]; out may be rh."""
    nb = AcolT.shape[1]
    for b in range(m):
        row = AcolT[idx[b]]
        y = x[idx[b]] if by_node else x[b]
        if b == 0:
            for i in range(nb):
                out[i] = rh[i] - row[i] * y
        else:
            for i in range(nb):
                out[i] -= row[i] * y
    if m == 0:
        for i in range(nb):
            out[i] = rh[i]


@njit(cache=True, fastmath=_FAST, _nrt=False)
def _apply_forces(qn, rh, lam, st, sz, idx, m, mu, spr, spt, spz, Acol):
    """q_n -= s phi_b^T g lam and rh -= A lam: the contact and friction forces lam_j (e_r + mu s_j)
    of the m nodes idx[:m] moved into the modal update. spr, spt, spz: radial, theta and z
    rows of phi scaled by s, (n_b, n_pad) each (contiguous rows: the mode loop vectorises);
    Acol[j]: column j of the modal update's compliance A = Phi_r S Phi_b^T g with node j's
    friction direction, stored as a row."""
    for b in range(m):
        j = idx[b]
        lj = lam[j]
        _add_row(qn, spr, spt, spz, j, lj, mu * st[j] * lj, mu * sz[j] * lj)
    _correct(rh, Acol, idx, lam, m, rh, True)


@njit(cache=True, fastmath=_FAST, _nrt=False)
def _sliding_direction(dtj, dzj, vscale, rj, om):
    """(|v|, v_theta / |v|, v_z / |v|) of a node's velocity relative to the casing,
    v = (dtj vscale + rj Omega, dzj vscale), m/s and -, from its theta and z increments
    dtj, dzj (m) and its signed radius rj (m); the unit part is (0, 0) under 1e-12 m/s."""
    vtj = dtj * vscale + rj * om
    vzj = dzj * vscale
    nrm = math.sqrt(vtj * vtj + vzj * vzj)
    if nrm > 1e-12:
        inv = 1.0 / nrm
        return nrm, vtj * inv, vzj * inv
    return nrm, 0.0, 0.0


# inlined by numba, not left to LLVM: called, this helper ran otherwise from numba's cache
# than as compiled in the process (another rounding: 3.8e-6 of an LE amplitude after 20
# revolutions, tests/hbm/test_jit.py), so a sweep's speeds depended on which workers compiled
@njit(cache=True, fastmath=_FAST, _nrt=False, inline="always")
def _redirect(inc, qn, qb, pt, pz, lam, idx, m, rho, om, vscale, st, sz, mu, rows, mats, u, ang, tol):
    """One update of the active nodes' unit sliding directions (st, sz) towards the fixed point
    s = u(s), u the direction of the step's centred velocity with its contact forces lam
    along s: (v_theta + s rho Omega, v_z) / |.|. Computed on the nodes: node j's theta and z
    increments of the prediction, inc[0:2, j] (from qn, the prediction, and qb; computed
    here where inc[2, j] == 0), less sum_b lam_b times node b's rows of the theta and z
    compliance with its friction (rows[1], rows[2]; rows[0] the radial one). Returns the
    largest |u - s|_1 over the m active nodes idx[:m] (the residual); when it is at most
    tol nothing moves. Where u turns against s at a node (u . s < 0, the relative sliding
    reverses within the step: the node sticks, which sliding friction has no direction for)
    there is no fixed point; it returns -1 and moves nothing. Else a node's first move in
    the step is s = u; from its second on, a secant step on its angle through this move's
    residual (the angle from s to u) and the last one's, the direction rotated by it:
    where the step's friction moves the direction back and forth (a node dragged along the
    casing past its lock) the plain update alternates and grows, which the secant does not.
    Angles are taken only from the second move on, as differences (one atan2 of a cross
    and a dot product, the first move's when the second comes): with absolute angles every
    move cost two atan2, a cosine and a sine (8 % of a contact-heavy march's samples, perf;
    benchmarks/README.md, *Time integration*). Each moved node's three rows follow (mats: the
    (r, theta, z) x (r, theta, z) compliance blocks, transposed). A node sliding at under
    1e-12 m/s keeps its direction. u: (2, n_b) work; ang: (3, n_b) state between moves,
    row 2 = 0 before a node's first move in the step (the caller's reset), then +-1 with
    rows 0-1 the direction before it, then +-2 with rows 0-1 the last step and residual,
    rad; the sign, that of s_theta before the first move, is the theta axis the angles are
    measured along."""
    change = 0.0
    for a in range(m):
        j = idx[a]
        if inc[2, j] == 0.0:
            inc[0, j], inc[1, j] = _node_increments(qn, qb, pt, pz, j)
            inc[2, j] = 1.0
        dtj = inc[0, j]
        dzj = inc[1, j]
        for b in range(m):
            k = idx[b]
            dtj -= lam[k] * rows[1, k, j]
            dzj -= lam[k] * rows[2, k, j]
        nrm, a_t, a_z = _sliding_direction(dtj, dzj, vscale, rho[j], om)
        u[0, j] = st[j]
        u[1, j] = sz[j]
        if nrm > 1e-12:
            u[0, j] = a_t
            u[1, j] = a_z
            if u[0, j] * st[j] + u[1, j] * sz[j] < 0.0:
                return -1.0
            change = max(change, abs(u[0, j] - st[j]) + abs(u[1, j] - sz[j]))
    if change <= tol:
        return change
    for a in range(m):
        j = idx[a]
        if u[0, j] == st[j] and u[1, j] == sz[j]:
            continue
        k = ang[2, j]
        if k == 0.0:  # the node's first move in this step: s = u, the old s kept for the secant
            # angles from the theta axis the node slides along: a mirror image (theta -> -theta)
            ang[2, j] = 1.0 if st[j] >= 0.0 else -1.0  # then makes the same numbers, to the bit
            ang[0, j] = st[j]
            ang[1, j] = sz[j]
            st[j] = u[0, j]
            sz[j] = u[1, j]
        else:
            sgn = 1.0 if k > 0.0 else -1.0
            if k == sgn:  # the second move: the first one's step, which was its residual
                ang[0, j] = math.atan2(sgn * (ang[0, j] * sz[j] - ang[1, j] * st[j]),
                                       ang[0, j] * st[j] + ang[1, j] * sz[j])
                ang[1, j] = ang[0, j]
                ang[2, j] = 2.0 * sgn
            # the residual, the angle from s to u (the cross product on mirrored axes takes sgn)
            res = math.atan2(sgn * (st[j] * u[1, j] - sz[j] * u[0, j]), st[j] * u[0, j] + sz[j] * u[1, j])
            step = res
            if res != ang[1, j]:  # secant through the last step (ang[0]) and residual (ang[1])
                step = -res * ang[0, j] / (res - ang[1, j])
            ang[0, j] = step
            ang[1, j] = res
            c = math.cos(step)
            sn = math.sin(step)
            t = st[j]
            st[j] = t * c - sgn * sz[j] * sn
            sz[j] = sgn * t * sn + sz[j] * c
        _friction_rows(rows, mats, j, mu * st[j], mu * sz[j])
    return change


@njit(cache=True, fastmath=_FAST, _nrt=False)
def _friction_rows(rows, mats, j, ft, fz):
    """rows[c, j] = mats[c, 0, j] + ft mats[c, 1, j] + fz mats[c, 2, j] for c = r, theta, z: the
    radial, theta and z displacements of every node per unit normal force at node j with its
    friction (ft, fz = mu s_theta, mu s_z); mats[c, e]: the compliance of c per force along e,
    transposed (a node's column is a row)."""
    for c in range(rows.shape[0]):
        _compliance_row(rows[c], mats[c, 0], mats[c, 1], mats[c, 2], j, ft, fz)


@njit(cache=True, fastmath=_FAST, _nrt=False)
def _first_at_or_after(step, start, stride):
    """(block index, step) of the first recording position start + k stride >= step, k >= 0."""
    if step <= start:
        return 0, start
    k = (step - start + stride - 1) // stride
    return k, start + k * stride


@njit(cache=True, fastmath=_FAST)
def run_steps(lin, bnd, comp, geo, cas, profile, par, state, rec, rec_rows, rec_frows, fnodes,
              out_x, out_f, out_sec, out_ext, stats, counts):
    """Advance the march by n_steps from the state at step step0 (see the module docstring).

    lin = (c1, c2, s, coff): the modal recurrence, (n,) each and (n, n).
    bnd = (prT, pr, pt, pz): radial rows transposed (n, n_bp) (padded to 12 columns when
        n_b <= 12), and the radial, theta and z rows (n_b, n).
    comp = (a_rr, a_rt, a_rz, g_rr, g_rt, g_rz, a_tr, a_tt, a_tz, a_zr, a_zt, a_zz): (n_b, n_b)
        each; a_ce = Phi_c S Phi_e^T (the modal update's compliance of c per force along e),
        g = the static boundary compliance (massless scheme).
    geo = (s rho, s theta), (n_b,) each, m and rad, s = +1 or -1 the sense of rotation: node j
        meets the casing at tau + s theta_j and slides at v_theta + s rho_j Omega (see hbm.ti.march).
        cas = (c, p, w, n_l) of eq. (28).
    profile: (P, n_b), m: d_j at steps 0 .. P - 1 when the casing's period is P whole steps
        (hbm.ti.march.casing_profile); d_j at step m is then row m mod P, which spares the
        casing law's floor at every node and step and its exponential at every node near
        the casing (a speed then takes 0.78 to 0.86 of its time: benchmarks/README.md,
        *Time integration*). (0, n_b): the law is evaluated at every step.
    par = (mu, Omega, dt, has_coff, massless, step0, n_steps, direction_tol): direction_tol,
        the sliding direction's tolerance (DIRECTION_TOL).
    state = (q, qm, lam_prev, st_prev, sz_prev, idx_prev, m_prev): q_{step0}, q_{step0-1} (n,)
        and the last step's contact: its m_prev active nodes idx_prev[:m_prev] (m_prev: (1,)
        int), their unit sliding directions (st_prev, sz_prev) and (massless scheme: the
        forces pending for the next step) lam_prev, (n_b,) each; all updated in place, so
        that a march run in chunks is the march run in one call, to the bit.
    rec = (start, stride, n_samples, section_stride, extreme_stride): see hbm.ti.march.Recording.
    rec_rows (n_x, n): recorded dof in modal coordinates; rec_frows (n_x, 3 n_b): their static
    response to the boundary forces (massless scheme). fnodes (n_f,): recorded force nodes.
    out_x (n_samples, n_x), out_f (n_samples, n_f, 4): per force block, the means of lam, of
    the friction's theta and z components and the number of steps with lam > 0 (a whole
    number), out_sec (n_sec, n_b),
    out_ext (n_blocks, 2, n_b): radial max and min per block; stats = [max penetration,
    min multiplier], counts = [contact steps, active-set failures, steps solved with the
    prediction's sliding direction]: accumulated in place.

    """
    c1, c2, s, coff = lin
    prT, pr, pt, pz = bnd
    a_rr, a_rt, a_rz, g_rr, g_rt, g_rz, a_tr, a_tt, a_tz, a_zr, a_zt, a_zz = comp
    rho, theta = geo  # signed by the sense of rotation
    clearance, penetration, width, n_lobes = cas
    mu, om, dt, has_coff, massless, step0, n_steps, dir_tol = par
    q_state, qm_state, lam_prev, st_prev, sz_prev, idx_prev, m_prev = state
    start, stride, n_out, sec_stride, ext_stride = rec
    n = c1.shape[0]
    nb = a_rr.shape[0]
    fast = prT.shape[1] == FAST_NODES and not has_coff
    nx = rec_rows.shape[0]
    nf = fnodes.shape[0]
    n_sec = out_sec.shape[0]
    n_ext = out_ext.shape[0]
    # The modal vectors and boundary rows the step loops over, padded with zeros to a multiple
    # of 16 modes: LLVM's vectorised mode loops take 16 at a time and left the rest (7 of 39
    # modes on rotor 67) to a scalar chain of dependent FMAs: 8 % of a contact-heavy march.
    # The padded entries stay zero (their rows are zero).
    npad = ((n + 15) // 16) * 16
    Q = np.zeros((3, npad))
    q = Q[0]
    qm = Q[1]
    qn = Q[2]
    for k in range(n):
        q[k] = q_state[k]
        qm[k] = qm_state[k]
    P = np.zeros((5, nb, npad))  # theta and z rows; radial, theta and z rows scaled by s
    for j in range(nb):
        for k in range(n):
            P[0, j, k] = pt[j, k]
            P[1, j, k] = pz[j, k]
            P[2, j, k] = s[k] * pr[j, k]
            P[3, j, k] = s[k] * pt[j, k]
            P[4, j, k] = s[k] * pz[j, k]
    pt = P[0]
    pz = P[1]
    spr = P[2]
    spt = P[3]
    spz = P[4]
    vel = np.zeros(n)
    nbp = prT.shape[1]
    vlen = ((max(nbp, nb) + 7) // 8) * 8  # a row per vector (not the casing's width, unpacked above)
    V = np.zeros((11, vlen))  # the per-node vectors, side by side (see the module docstring)
    rh = V[0, :nbp]
    d = V[1, :nb]
    z = V[2, :nb]
    fac = V[3, :nb]
    lam = V[4, :nb]
    st = V[5, :nb]
    sz = V[6, :nb]
    rnew = V[7, :nb]  # radial displacements after the corrections of the active set's current iterate
    bm = V[8, :nb]
    emax = V[9, :nb]  # the current extreme block, kept here and written out when it ends:
    emin = V[10, :nb]  # stores into out_ext at every step cost ~10 % of a free step
    exact = np.zeros(nb, dtype=np.bool_)
    udir = np.zeros((2, nb))  # the sliding direction's passes: work,
    ang = np.zeros((3, nb))  # _redirect's state between a node's moves in a step (the secant's)
    inc = np.zeros((3, nb))  # each node's theta and z increments of the prediction (row 2: set)
    active = np.zeros(nb, dtype=np.bool_)
    idx = np.zeros(nb, dtype=np.int64)
    was_active = np.zeros(nb, dtype=np.bool_)  # the last step's final active set
    # where each node's forces go: fpos[j] its first position among the recorded force nodes,
    # fnext[a] the next position of the same node (-1: none)
    fpos = np.full(nb, -1, dtype=np.int64)
    fnext = np.full(max(nf, 1), -1, dtype=np.int64)
    for a in range(nf - 1, -1, -1):
        fnext[a] = fpos[fnodes[a]]
        fpos[fnodes[a]] = a
    Mats = np.zeros((17, nb, nb))
    # rows[c, j]: the (r, theta, z) displacements of every node per unit normal force at node j
    # with its friction direction (rows[0] = Acol, the LCP's; theta and z: the sliding
    # direction's passes); mats[c, e]: the compliance of c per force along e, transposed (a
    # node's column is a contiguous row)
    rows = Mats[0:3]
    mats = Mats[3:12].reshape((3, 3, nb, nb))
    Acol = rows[0]
    Acol_prev = Mats[12]
    Am = Mats[13]
    a_rrT, a_rtT, a_rzT = Mats[14], Mats[15], Mats[16]
    # the LCP's compliance: the modal update's (Carpenter) or the static boundary's (massless)
    A_rr, A_rt, A_rz = (g_rr, g_rt, g_rz) if massless else (a_rr, a_rt, a_rz)
    AT_rr, AT_rt, AT_rz = mats[0, 0], mats[0, 1], mats[0, 2]
    for i in range(nb):
        for j in range(nb):
            AT_rr[j, i] = A_rr[i, j]
            AT_rt[j, i] = A_rt[i, j]
            AT_rz[j, i] = A_rz[i, j]
            a_rrT[j, i] = a_rr[i, j]
            a_rtT[j, i] = a_rt[i, j]
            a_rzT[j, i] = a_rz[i, j]
            mats[1, 0, j, i] = a_tr[i, j]
            mats[1, 1, j, i] = a_tt[i, j]
            mats[1, 2, j, i] = a_tz[i, j]
            mats[2, 0, j, i] = a_zr[i, j]
            mats[2, 1, j, i] = a_zt[i, j]
            mats[2, 2, j, i] = a_zz[i, j]
    # a march run in chunks: the last call's last step was in contact on nodes idx_prev[:m_prev]
    # with directions (st_prev, sz_prev); they start this call's first step as they would have
    # started it in one call (its active set's first guess, its sliding directions' start, and
    # their compliance rows, which are work). Started afresh instead, a chunked march left the
    # one-call march within a few revolutions at 1e-6 s. The massless scheme's pending forces
    # act on rh through their compliance columns, work as well.
    for b in range(m_prev[0]):
        j = idx_prev[b]
        was_active[j] = True
        st[j] = st_prev[j]
        sz[j] = sz_prev[j]
        if massless:
            _compliance_row(Acol_prev, a_rrT, a_rtT, a_rzT, j, mu * st_prev[j], mu * sz_prev[j])
        elif mu != 0.0:
            _friction_rows(rows, mats, j, mu * st[j], mu * sz[j])
    n_prof = profile.shape[0]
    kp = (step0 + 1) % n_prof if n_prof else 0  # the profile's row of the step being computed
    if n_prof:
        for j in range(nb):  # every d_j is exact at every step
            exact[j] = True
    vscale = 1.0 / dt if massless else 0.5 / dt  # backward or centred difference
    margin = 1e-12 * (abs(clearance) + abs(penetration))
    cpp_margin = clearance + penetration + margin
    max_pen = stats[0]
    min_lam = stats[1]
    n_contact = counts[0]
    n_fail = counts[1]
    n_explicit = counts[2]
    inv_stride = 1.0 / stride
    # recording positions from the global step of the first state this call produces
    first = step0 + 1
    x_block, x_next = _first_at_or_after(first, start, stride)
    s_block, s_next = _first_at_or_after(first, start, sec_stride) if sec_stride > 0 else (0, -1)
    e_block = 0
    e_next = start
    if ext_stride > 0 and first > start:
        e_block = (first - start) // ext_stride
        e_next = start + e_block * ext_stride
    if e_block < n_ext:
        for j in range(nb):
            emax[j] = out_ext[e_block, 0, j]
            emin[j] = out_ext[e_block, 1, j]
    # force block b averages the multipliers of steps sf + b stride .. sf + (b + 1) stride - 1
    sf = start - stride // 2
    fshift = 0 if massless else 1  # lam computed at step m1 belongs to step m1 (massless) or m1 - 1
    f_block = (first - fshift - sf) // stride  # floor division: negative before the first block
    f_next = sf + (f_block + 1) * stride
    for it in range(n_steps):
        m1 = step0 + it + 1  # the step being computed
        tau = om * (m1 * dt)
        if fast:
            _predict_fast(c1, c2, q, qm, qn, prT, rh)
        else:
            _predict_general(c1, c2, s, coff, has_coff, dt, q, qm, qn, prT, rh, vel)
        if massless and m_prev[0] > 0:  # the static contact forces of the previous step
            _apply_forces(qn, rh, lam_prev, st_prev, sz_prev, idx_prev, m_prev[0], mu, spr, spt, spz, Acol_prev)
            m_prev[0] = 0
        if n_prof:
            any_pen = _profile_penetrations(profile, kp, rh, d, active)
            near = True
            kp += 1
            if kp == n_prof:
                kp = 0
        else:
            any_pen, near = _find_penetrations(tau, theta, rh, cas, margin, fac, z, d, exact, active)
        m = 0
        if any_pen:
            n_contact += 1
            for j in range(nb):
                if was_active[j] and exact[j]:
                    active[j] = True
            qb = q if massless else qm
            iterate = not massless and mu != 0.0
            for j in range(nb):  # 0: the direction is found when the node joins the active set
                inc[2, j] = 0.0
                ang[2, j] = 0.0  # no move of its direction yet in this step (_redirect)
                if not iterate or not was_active[j]:
                    st[j] = 0.0
                    sz[j] = 0.0
            # Carpenter's friction acts along the sliding direction at the step's centred
            # velocity, (q_{m+1} - q_{m-1}) / 2 dt, which depends on the step's own contact
            # forces: the step is solved with the prediction's velocity, then again with the
            # velocity it gives, until the direction moves by less than dir_tol. With the
            # prediction's alone, the step's impulses are missing from the direction at every
            # impact: an O(dt) error, 0.4 to 2.5 % of the LE amplitude at dt = 1e-7 to 4e-7 on
            # rotor 67 and a class changed at 400 and 650 rad/s (benchmarks/README.md, *Time
            # integration*). The massless scheme's forces reach the modes one step later: its
            # direction does not depend on them. A node active at the last step starts from
            # its last direction, which the step's forces seldom move by dir_tol (0.2 to 0.5
            # passes more per contact step on rotor 67, against 1.0 to 2.8 when every step
            # started from the prediction's velocity).
            # Where no direction settles (a sliding reversal: _redirect; or DIRECTION_PASSES
            # passes) the step is solved once more with the prediction's direction, the
            # explicit rule (counted in counts[2]). The passes work on the nodes (the step's
            # compliance), from the last pass's active set; the forces reach the modes once.
            converged = False
            explicit = False
            p = 0
            while True:
                if explicit:
                    for j in range(nb):
                        st[j] = 0.0
                        sz[j] = 0.0
                    n_explicit += 1
                # Active set from the prediction's penetrations and the last step's active nodes
                # still near the casing: drop the most negative multiplier, add the inactive node
                # pushed furthest beyond the casing, until neither exists (at most 4 n_b + 4
                # passes). From the penetrations alone, 60 % of the contact steps needed a second
                # pass to add a node pushed in by its neighbours' correction (1.60 passes per
                # contact step at 650 rad/s, on the default ROM); with the last step's nodes 1.23,
                # for a node kept and then dropped in 2 contact steps of 10^4. The solution is the
                # same (the active set converges to the same set, solved in the same order).
                converged = False
                for _ in range(4 * nb + 4):
                    m = 0
                    for j in range(nb):
                        if active[j]:
                            idx[m] = j
                            m += 1
                            if st[j] == 0.0 and sz[j] == 0.0:  # first time active in this step
                                if mu != 0.0:  # unit sliding direction (v_theta + s rho Omega, v_z) / |.|
                                    dtj, dzj = _node_increments(qn, qb, pt, pz, j)
                                    inc[0, j] = dtj
                                    inc[1, j] = dzj
                                    inc[2, j] = 1.0
                                    nrm, a_t, a_z = _sliding_direction(dtj, dzj, vscale, rho[j], om)
                                    if nrm > 1e-12:
                                        st[j] = a_t
                                        sz[j] = a_z
                                if iterate:
                                    _friction_rows(rows, mats, j, mu * st[j], mu * sz[j])
                                else:
                                    _compliance_row(Acol, AT_rr, AT_rt, AT_rz, j, mu * st[j], mu * sz[j])
                    for a in range(m):
                        i = idx[a]
                        for b in range(m):
                            Am[a, b] = Acol[idx[b], i]
                        bm[a] = rh[i] - d[i]
                    _solve_small(Am, bm, m)
                    worst = -1
                    wval = 0.0
                    for a in range(m):
                        if bm[a] < wval:
                            wval = bm[a]
                            worst = idx[a]
                    if worst >= 0:  # drop the most negative multiplier and re-solve
                        active[worst] = False
                        continue
                    for j in range(nb):
                        lam[j] = 0.0
                    for a in range(m):
                        lam[idx[a]] = bm[a]
                    worst = -1
                    wval = 0.0
                    _correct(rh, Acol, idx, bm, m, rnew, False)
                    for i in range(nb):
                        if not active[i]:
                            r_i = rnew[i]
                            if not exact[i]:
                                if (clearance - r_i) * fac[i] > cpp_margin and cpp_margin >= margin:
                                    continue  # still certainly free after the correction
                                d[i] = gap_at(z[i], clearance, penetration)
                                exact[i] = True
                            if r_i - d[i] > wval:
                                wval = r_i - d[i]
                                worst = i
                    if worst >= 0:  # an inactive node is pushed beyond the casing: add it
                        active[worst] = True
                        continue
                    converged = True
                    break
                if not converged:
                    for a in range(m):  # keep the last iterate, clipped to lam >= 0
                        lam[idx[a]] = max(bm[a], 0.0)
                if not iterate or explicit:
                    break
                res = _redirect(inc, qn, qb, pt, pz, lam, idx, m, rho, om, vscale, st, sz, mu, rows, mats, udir, ang,
                                dir_tol)
                if 0.0 <= res <= dir_tol:
                    break
                p += 1
                explicit = res < 0.0 or p == DIRECTION_PASSES
            if massless:  # r_m = Phi_r q_m - G lam_m; the forces reach the modes at m + 1
                _correct(rh, Acol, idx, lam, m, rh, True)
                for b in range(m):
                    j = idx[b]
                    idx_prev[b] = j
                    lam_prev[j] = lam[j]
                    st_prev[j] = st[j]
                    sz_prev[j] = sz[j]
                    _compliance_row(Acol_prev, a_rrT, a_rtT, a_rzT, j, mu * st[j], mu * sz[j])
                m_prev[0] = m
            else:  # forward increment: q_m -= s phi_b^T g lam and rh -= A lam
                for b in range(m):
                    j = idx[b]
                    lj = lam[j]
                    _add_row(qn, spr, spt, spz, j, lj, mu * st[j] * lj, mu * sz[j] * lj)
                if converged:
                    for i in range(nb):
                        rh[i] = rnew[i]
                else:
                    _correct(rh, Acol, idx, lam, m, rh, True)
            if not converged:
                n_fail += 1
            for b in range(m):
                if lam[idx[b]] < min_lam:
                    min_lam = lam[idx[b]]
            for j in range(nb):
                was_active[j] = active[j]
        else:
            for j in range(nb):
                was_active[j] = False
        if near:  # nodes ruled free by the bound are certainly below the casing
            for j in range(nb):  # branch-free, as the extremes below
                max_pen = max(max_pen, rh[j] - d[j] if exact[j] else -np.inf)
        # forces: block means, and the steps in contact per block (counters, not divisions: an
        # integer division costs as much as a mode); nothing to do on a step without contact
        if m1 - fshift == f_next:
            f_block += 1
            f_next += stride
        if m > 0 and 0 <= f_block < n_out:
            for b in range(m):  # the active nodes only: the others carry no force
                j = idx[b]
                a = fpos[j]
                while a >= 0:
                    out_f[f_block, a, 0] += lam[j] * inv_stride
                    out_f[f_block, a, 1] -= mu * st[j] * lam[j] * inv_stride
                    out_f[f_block, a, 2] -= mu * sz[j] * lam[j] * inv_stride
                    out_f[f_block, a, 3] += 1.0 if lam[j] > 0.0 else 0.0  # a step with a force
                    a = fnext[a]
        # record the state at step m1: radial extremes of its block, the sampled dof (massless:
        # with the static response to this step's forces) and the Poincare section
        if m1 >= start:
            if ext_stride > 0 and m1 == e_next + ext_stride:
                if e_block < n_ext:
                    for j in range(nb):
                        out_ext[e_block, 0, j] = emax[j]
                        out_ext[e_block, 1, j] = emin[j]
                e_block += 1
                e_next += ext_stride
                if e_block < n_ext:
                    for j in range(nb):
                        emax[j] = out_ext[e_block, 0, j]
                        emin[j] = out_ext[e_block, 1, j]
            if e_block < n_ext:
                for j in range(nb):  # max and min, not branches: 5 % of a step (mispredictions)
                    emax[j] = max(emax[j], rh[j])
                    emin[j] = min(emin[j], rh[j])
            if m1 == x_next:
                if x_block < n_out:
                    for a in range(nx):
                        acc = 0.0
                        for k in range(n):
                            acc += rec_rows[a, k] * qn[k]
                        if massless:
                            for b in range(m):
                                j = idx[b]
                                acc -= lam[j] * (rec_frows[a, 3 * j] + mu * (st[j] * rec_frows[a, 3 * j + 1]
                                                                             + sz[j] * rec_frows[a, 3 * j + 2]))
                        out_x[x_block, a] = acc
                x_block += 1
                x_next += stride
            if m1 == s_next:
                if s_block < n_sec:
                    for j in range(nb):
                        out_sec[s_block, j] = rh[j]
                s_block += 1
                s_next += sec_stride
        # rotate the state
        tmp = qm
        qm = q
        q = qn
        qn = tmp
    if e_block < n_ext:
        for j in range(nb):
            out_ext[e_block, 0, j] = emax[j]
            out_ext[e_block, 1, j] = emin[j]
    stats[0] = max_pen
    stats[1] = min_lam
    counts[0] = n_contact
    counts[1] = n_fail
    counts[2] = n_explicit
    for k in range(n):
        q_state[k] = q[k]
        qm_state[k] = qm[k]
    if not massless:  # (the massless scheme's pending forces are these already)
        mm = 0
        for j in range(nb):
            if was_active[j]:
                idx_prev[mm] = j
                st_prev[j] = st[j]
                sz_prev[j] = sz[j]
                mm += 1
        m_prev[0] = mm
