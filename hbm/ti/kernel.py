"""Compiled step loop of the central-difference march (numba): one loop, two contact schemes.

Every step m (t_m = m dt) does, in this order:
1. predict: q_hat_m = c1 q_{m-1} - c2 q_{m-2} (- s C_off v for non-modal damping) and the
   radial boundary displacements r_hat = Phi_r q_hat, in one pass over the modes;
2. (massless scheme only) apply the contact forces of step m-1 to q_m: they act on the
   modal dof one step later, as any force of central differences;
3. find the nodes beyond the casing of eq. (28) (the casing law of hbm.contact.casing,
   compiled here from its one source) and solve the linear complementarity problem
   r = r_hat - A lam <= d, lam >= 0, lam (d - r) = 0 on the penetrating nodes by an active
   set; A = the scheme's compliance (with the friction columns of the sliding direction);
4. (Carpenter) apply the forward-increment multipliers to q_m: the constraint holds at m;
5. record.

Carpenter, Taylor and Katona (1991): lam_{m-1} is chosen so that r_m <= d_m; A = Phi_r S
Phi_b^T g, S = diag(dt^2 / (1 + a_k)): the impulse a step needs to stop the boundary.
Massless boundary: r_m = Phi_r q_m - G lam_m with G the residual (static) flexibility of
the boundary; lam_m is a static projection at t_m, applied to the modes at the next step.

All arrays are preallocated by the caller (hbm.ti.march); the loop allocates only its own
work arrays once per call, so a march may be run in chunks (the state is read from and
written back to `state`, and recording positions count from the global step index).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from hbm.contact import casing as _casing_law

# reassociation lets LLVM vectorise the modal sums; contraction allows FMAs. No other
# fast-math flag: inf and nan must keep their meaning (the diagnostics start at +-inf).
_FAST = {"reassoc", "contract"}

#: The casing law of eq. (28), compiled from the same source as hbm.contact.casing.casing_distance.
lobe_coordinate = njit(cache=True, inline="always")(_casing_law.lobe_coordinate)
gap_at = njit(cache=True, inline="always")(_casing_law.gap_at)

#: Radial rows are padded to this many columns when n_b <= FAST_NODES (see _predict_fast).
FAST_NODES = 12


@njit(cache=True, fastmath=_FAST, inline="always")
def _predict_fast(c1, c2, q, qm, qn, prT, rh):
    """q_hat = c1 q - c2 qm and rh = prT^T q_hat for n_b <= 12 (prT padded to 12 columns).

    Twelve scalar accumulators that LLVM keeps in (vector) registers; an array accumulator
    is reloaded for every mode (4-5 times slower)."""
    r0 = r1 = r2 = r3 = r4 = r5 = r6 = r7 = r8 = r9 = r10 = r11 = 0.0
    for k in range(c1.shape[0]):
        v = c1[k] * q[k] - c2[k] * qm[k]
        qn[k] = v
        p = prT[k]
        r0 += p[0] * v
        r1 += p[1] * v
        r2 += p[2] * v
        r3 += p[3] * v
        r4 += p[4] * v
        r5 += p[5] * v
        r6 += p[6] * v
        r7 += p[7] * v
        r8 += p[8] * v
        r9 += p[9] * v
        r10 += p[10] * v
        r11 += p[11] * v
    rh[0] = r0
    rh[1] = r1
    rh[2] = r2
    rh[3] = r3
    rh[4] = r4
    rh[5] = r5
    rh[6] = r6
    rh[7] = r7
    rh[8] = r8
    rh[9] = r9
    rh[10] = r10
    rh[11] = r11


@njit(cache=True, fastmath=_FAST, inline="always")
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


@njit(cache=True, fastmath=_FAST, inline="always")
def _find_penetrations(tau, theta, rh, cas, bound, fac, z, d, exact, active):
    """Mark the nodes with rh_j >= d_j(tau); return (any penetration, any node near the casing).

    The casing law (exp) is evaluated only for the nodes that a cheap test cannot rule out:
    e^{-z^2} <= 1 / (1 + z^2 + z^4 / 2), so d_j >= c - (c + p) / (1 + z^2 + z^4 / 2) when
    c + p >= 0, and a node with (c - r_j)(1 + z^2 + z^4 / 2) > (c + p) + margin is free. The test
    uses its own z (multiplications by reciprocals instead of the law's divisions): the two
    differ by round-off, which the margin (bound[4]: 1e-12 (|c| + |p|), far above round-off and
    far below any physical gap) covers. With c + p < 0 every node is evaluated.
    bound = (1 / period, period, pi / n_l, 1 / w, margin); fac_j = 1 + z^2 + z^4 / 2 is kept
    for the same test after the contact correction. Only nodes near the casing (exact_j
    True) get d_j; the others are certainly free and their d_j is stale."""
    clearance, penetration, width, n_lobes = cas
    inv_period, period, centre, inv_w, margin = bound
    cpp = clearance + penetration
    nb = theta.shape[0]
    near = False
    for j in range(nb):
        x = tau + theta[j]
        zb = (x - period * np.floor(x * inv_period) - centre) * inv_w
        z2 = zb * zb
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
                zj = lobe_coordinate(tau + theta[j], n_lobes, width)
                z[j] = zj
                d[j] = gap_at(zj, clearance, penetration)
                if rh[j] >= d[j]:
                    active[j] = True
                    any_pen = True
    return any_pen, near


@njit(cache=True, fastmath=_FAST, inline="always")
def _sliding_direction(j, qn, qb, vscale, pt, pz, rho_om):
    """Unit sliding direction (s_theta, s_z) of node j: relative velocity (v_theta + rho Omega,
    v_z) with v = (phi_t, phi_z) (qn - qb) vscale; (0, 0) when it vanishes."""
    vt = 0.0
    vz = 0.0
    for k in range(qn.shape[0]):
        dq = qn[k] - qb[k]
        vt += pt[j, k] * dq
        vz += pz[j, k] * dq
    vt = vt * vscale + rho_om
    vz = vz * vscale
    nrm = math.sqrt(vt * vt + vz * vz)
    if nrm > 1e-12:
        return vt / nrm, vz / nrm
    return 0.0, 0.0


@njit(cache=True, inline="always")
def _solve_small(A, b, m):
    """Solve A[:m, :m] x = b[:m] in place by Gaussian elimination with partial pivoting."""
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


@njit(cache=True, fastmath=_FAST, inline="always")
def _solve_contact(tau, rh, d, z, fac, exact, active, A_rr, A_rt, A_rz, mu, cas, margin, theta, slide, lam,
                   st, sz, has_dir, idx, Acol, Am, bm):
    """Active-set solution of the contact LCP on the nodes marked `active` (the prediction's
    penetrations, a good first guess): drop the most negative multiplier, add the inactive
    node pushed furthest beyond the casing, until neither exists (at most 4 n_b + 4 passes).

    slide = (qn, qb, vscale, pt, pz, rho, Om): what the sliding directions need. On return
    lam (n_b,) holds the multipliers (0 off the active set), st, sz the sliding directions
    of the active nodes, idx[:m] the active nodes, Acol[:, j] the column of A for node j
    (friction included). Returns (m, converged)."""
    qn, qb, vscale, pt, pz, rho, om = slide
    clearance, penetration, width, n_lobes = cas
    cpp_margin = clearance + penetration + margin
    nb = d.shape[0]
    for j in range(nb):
        has_dir[j] = False
        lam[j] = 0.0
    m = 0
    for _ in range(4 * nb + 4):
        m = 0
        for j in range(nb):
            if active[j]:
                idx[m] = j
                m += 1
                if not has_dir[j]:
                    has_dir[j] = True
                    if mu != 0.0:
                        st[j], sz[j] = _sliding_direction(j, qn, qb, vscale, pt, pz, rho[j] * om)
                    else:
                        st[j] = 0.0
                        sz[j] = 0.0
                    for i in range(nb):
                        Acol[i, j] = A_rr[i, j] + mu * (A_rt[i, j] * st[j] + A_rz[i, j] * sz[j])
        for a in range(m):
            i = idx[a]
            for b in range(m):
                Am[a, b] = Acol[i, idx[b]]
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
        worst = -1
        wval = 0.0
        for i in range(nb):
            if not active[i]:
                r_i = rh[i]
                for b in range(m):
                    r_i -= Acol[i, idx[b]] * bm[b]
                if not exact[i] and not ((clearance - r_i) * fac[i] > cpp_margin and cpp_margin >= margin):
                    # ruled free before the correction, maybe not after: evaluate the casing
                    z[i] = lobe_coordinate(tau + theta[i], n_lobes, width)
                    d[i] = gap_at(z[i], clearance, penetration)
                    exact[i] = True
                if not exact[i]:
                    continue
                if r_i - d[i] > wval:
                    wval = r_i - d[i]
                    worst = i
        if worst >= 0:  # an inactive node is pushed beyond the casing: add it
            active[worst] = True
            continue
        for a in range(m):
            lam[idx[a]] = bm[a]
        return m, True
    for a in range(m):  # not converged: keep the last iterate, clipped to lam >= 0
        lam[idx[a]] = max(bm[a], 0.0)
    return m, False


@njit(cache=True, fastmath=_FAST, inline="always")
def _apply_forces(qn, rh, lam, st, sz, idx, m, mu, s, pr, pt, pz, a_rr, a_rt, a_rz):
    """q_n -= s phi_b^T g lam and rh -= A lam: the contact and friction forces lam_j (e_r + mu s_j)
    of the m nodes idx[:m] moved into the modal update (A = Phi_r S Phi_b^T g).
    pr, pt, pz: radial, theta and z rows of phi, (n_b, n) each (contiguous rows: the mode loop vectorises)."""
    n = qn.shape[0]
    nb = a_rr.shape[0]
    for b in range(m):
        j = idx[b]
        lj = lam[j]
        ft = mu * st[j] * lj
        fz = mu * sz[j] * lj
        for k in range(n):
            qn[k] -= s[k] * (pr[j, k] * lj + pt[j, k] * ft + pz[j, k] * fz)
    for i in range(nb):
        acc = rh[i]
        for b in range(m):
            j = idx[b]
            acc -= (a_rr[i, j] + mu * (a_rt[i, j] * st[j] + a_rz[i, j] * sz[j])) * lam[j]
        rh[i] = acc


@njit(cache=True, fastmath=_FAST, inline="always")
def _first_at_or_after(step, start, stride):
    """(block index, step) of the first recording position start + k stride >= step, k >= 0."""
    if step <= start:
        return 0, start
    k = (step - start + stride - 1) // stride
    return k, start + k * stride


@njit(cache=True, fastmath=_FAST)
def run_steps(lin, bnd, comp, geo, cas, par, state, rec, rec_rows, rec_frows, fnodes,
              out_x, out_f, out_sec, out_ext, stats, counts):
    """Advance the march by n_steps from the state at step step0 (see the module docstring).

    lin = (c1, c2, s, coff): the modal recurrence, (n,) each and (n, n).
    bnd = (prT, pr, pt, pz): radial rows transposed (n, n_bp) (padded to 12 columns when
        n_b <= 12), and the radial, theta and z rows (n_b, n).
    comp = (a_rr, a_rt, a_rz, g_rr, g_rt, g_rz): (n_b, n_b) each; a = Phi_r S Phi^T (the
        modal update's compliance), g = the static boundary compliance (massless scheme).
    geo = (rho, theta), (n_b,) each, m and rad. cas = (c, p, w, n_l) of eq. (28).
    par = (mu, Omega, dt, has_coff, massless, step0, n_steps).
    state = (q, qm, lam_prev, st_prev, sz_prev, idx_prev, m_prev): q_{step0}, q_{step0-1} (n,)
        and the massless scheme's pending forces; all updated in place (m_prev: (1,) int).
    rec = (start, stride, n_samples, section_stride, extreme_stride): see hbm.ti.march.Recording.
    rec_rows (n_x, n): recorded dof in modal coordinates; rec_frows (n_x, 3 n_b): their static
    response to the boundary forces (massless scheme). fnodes (n_f,): recorded force nodes.
    out_x (n_samples, n_x), out_f (n_samples, n_f, 3), out_sec (n_sec, n_b),
    out_ext (n_blocks, 2, n_b): radial max and min per block; stats = [max penetration,
    min multiplier], counts = [contact steps, active-set failures]: accumulated in place.
    """
    c1, c2, s, coff = lin
    prT, pr, pt, pz = bnd
    a_rr, a_rt, a_rz, g_rr, g_rt, g_rz = comp
    rho, theta = geo
    mu, om, dt, has_coff, massless, step0, n_steps = par
    q_state, qm_state, lam_prev, st_prev, sz_prev, idx_prev, m_prev = state
    start, stride, n_out, sec_stride, ext_stride = rec
    n = c1.shape[0]
    nb = a_rr.shape[0]
    fast = prT.shape[1] == FAST_NODES and not has_coff
    nx = rec_rows.shape[0]
    nf = fnodes.shape[0]
    n_sec = out_sec.shape[0]
    n_ext = out_ext.shape[0]
    q = q_state.copy()
    qm = qm_state.copy()
    qn = np.zeros(n)
    rh = np.zeros(prT.shape[1])
    vel = np.zeros(n)
    d = np.zeros(nb)
    z = np.zeros(nb)
    fac = np.zeros(nb)
    exact = np.zeros(nb, dtype=np.bool_)
    active = np.zeros(nb, dtype=np.bool_)
    has_dir = np.zeros(nb, dtype=np.bool_)
    lam = np.zeros(nb)
    st = np.zeros(nb)
    sz = np.zeros(nb)
    idx = np.zeros(nb, dtype=np.int64)
    Acol = np.zeros((nb, nb))
    Am = np.zeros((nb, nb))
    bm = np.zeros(nb)
    A_rr, A_rt, A_rz = (g_rr, g_rt, g_rz) if massless else (a_rr, a_rt, a_rz)
    vscale = 1.0 / dt if massless else 0.5 / dt
    clearance, penetration, width, n_lobes = cas
    margin = 1e-12 * (abs(clearance) + abs(penetration))
    bound = (n_lobes / (2.0 * math.pi), 2.0 * math.pi / n_lobes, math.pi / n_lobes, 1.0 / width, margin)
    max_pen = stats[0]
    min_lam = stats[1]
    n_contact = counts[0]
    n_fail = counts[1]
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
    # force block b averages the multipliers of steps sf + b stride .. sf + (b + 1) stride - 1
    sf = start - stride // 2
    fshift = 0 if massless else 1  # lam computed at step m1 belongs to step m1 (massless) or m1 - 1
    f0 = first - fshift
    if f0 >= sf:
        f_block = (f0 - sf) // stride
        f_next = sf + (f_block + 1) * stride
    else:
        f_block = -1 - (sf - f0 - 1) // stride
        f_next = sf + (f_block + 1) * stride
    for it in range(n_steps):
        m1 = step0 + it + 1  # the step being computed
        tau = om * (m1 * dt)
        if fast:
            _predict_fast(c1, c2, q, qm, qn, prT, rh)
        else:
            _predict_general(c1, c2, s, coff, has_coff, dt, q, qm, qn, prT, rh, vel)
        if massless and m_prev[0] > 0:
            _apply_forces(qn, rh, lam_prev, st_prev, sz_prev, idx_prev, m_prev[0], mu, s, pr, pt, pz,
                          a_rr, a_rt, a_rz)
            m_prev[0] = 0
        any_pen, near = _find_penetrations(tau, theta, rh, cas, bound, fac, z, d, exact, active)
        m = 0
        if any_pen:
            n_contact += 1
            m, ok = _solve_contact(tau, rh, d, z, fac, exact, active, A_rr, A_rt, A_rz, mu, cas, margin, theta,
                                   (qn, q if massless else qm, vscale, pt, pz, rho, om),
                                   lam, st, sz, has_dir, idx, Acol, Am, bm)
            if not ok:
                n_fail += 1
            if massless:  # r_m = Phi_r q_m - G lam_m; the forces reach the modes at m + 1
                for i in range(nb):
                    acc = rh[i]
                    for b in range(m):
                        acc -= Acol[i, idx[b]] * lam[idx[b]]
                    rh[i] = acc
                for b in range(m):
                    j = idx[b]
                    idx_prev[b] = j
                    lam_prev[j] = lam[j]
                    st_prev[j] = st[j]
                    sz_prev[j] = sz[j]
                m_prev[0] = m
            else:
                _apply_forces(qn, rh, lam, st, sz, idx, m, mu, s, pr, pt, pz, a_rr, a_rt, a_rz)
            for b in range(m):
                if lam[idx[b]] < min_lam:
                    min_lam = lam[idx[b]]
        if near:  # nodes ruled free by the bound are certainly below the casing
            for j in range(nb):
                if exact[j] and rh[j] - d[j] > max_pen:
                    max_pen = rh[j] - d[j]
        # forces: block means (counters, not divisions: an integer division costs as much as a mode)
        if m1 - fshift == f_next:
            f_block += 1
            f_next += stride
        if m > 0 and 0 <= f_block < n_out:
            for a in range(nf):
                j = fnodes[a]
                if lam[j] != 0.0:
                    out_f[f_block, a, 0] += lam[j] * inv_stride
                    out_f[f_block, a, 1] -= mu * st[j] * lam[j] * inv_stride
                    out_f[f_block, a, 2] -= mu * sz[j] * lam[j] * inv_stride
        # record the state at step m1
        if m1 >= start:
            if ext_stride > 0 and m1 == e_next + ext_stride:
                e_block += 1
                e_next += ext_stride
            if e_block < n_ext:
                for j in range(nb):
                    if rh[j] > out_ext[e_block, 0, j]:
                        out_ext[e_block, 0, j] = rh[j]
                    if rh[j] < out_ext[e_block, 1, j]:
                        out_ext[e_block, 1, j] = rh[j]
            if m1 == x_next and x_block < n_out:
                for a in range(nx):
                    acc = 0.0
                    for k in range(n):
                        acc += rec_rows[a, k] * qn[k]
                    if massless:
                        for b in range(m):
                            j = idx[b]
                            lj = lam[j]
                            acc -= lj * (rec_frows[a, 3 * j] + mu * (st[j] * rec_frows[a, 3 * j + 1]
                                                                     + sz[j] * rec_frows[a, 3 * j + 2]))
                    out_x[x_block, a] = acc
                x_block += 1
                x_next += stride
            if m1 == s_next and s_block < n_sec:
                for j in range(nb):
                    out_sec[s_block, j] = rh[j]
                s_block += 1
                s_next += sec_stride
        # rotate the state
        tmp = qm
        qm = q
        q = qn
        qn = tmp
    stats[0] = max_pen
    stats[1] = min_lam
    counts[0] = n_contact
    counts[1] = n_fail
    for k in range(n):
        q_state[k] = q[k]
        qm_state[k] = qm[k]
