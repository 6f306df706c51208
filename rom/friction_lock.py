"""Friction lock: does sliding friction push a contact node into the casing or away from it?

Statics of the ROM at its contact nodes. With G the static compliance of the boundary dof
(the inverse of the statically condensed stiffness: G = [K^-1]_bb, m/N, local r, theta, z
per node), a normal force lam_k >= 0 on node k (the casing pushes inward: force -lam_k e_r,
the convention of hbm.contact.normal) with sliding friction mu lam_k against the blade's
motion (force -mu lam_k s e_theta: the tip slides at about s rho Omega e_theta, s = +1 or
-1 the sense of rotation, hbm.contact.friction) moves the radial dof by

    r_j = -sum_k (G_rr + s mu G_rtheta)_jk lam_k = -(A(mu) lam)_j.

One node: A_jj = G_rr,jj + s mu G_rtheta,jj < 0 means that pressing node j harder drags it
further out, into the casing: the contact cannot release it (friction lock, a static
wedging), which happens above mu_j = -G_rr,jj / (s G_rtheta,jj) when s G_rtheta,jj < 0.
Several nodes in contact at once: the contact problem r = r_free - A lam, gap >= 0,
lam >= 0, complementary, has a unique solution for every r_free only while A(mu) is a
P-matrix (every principal minor > 0); mu_set is the smallest mu at which one of its
principal minors vanishes. A(0) = G_rr is symmetric positive definite, so 0 < mu_set <=
min_j mu_j.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np

from rom.rotation import check_sign

#: Above this many contact nodes the P-matrix test visits only the subsets of up to
#: _MAX_EXACT nodes (2^n subsets otherwise): mu_set is then an upper bound.
_MAX_EXACT = 12


@dataclass(frozen=True)
class FrictionLock:
    """The static friction-lock table of a ROM (independent of mu: evaluate any mu with
    `radial_compliance`).

    rotation: sense of rotation s, +1 or -1. compliance_rr: G[r_j, r_k], (n_b, n_b), m/N.
    compliance_rtheta: G[r_j, theta_k], (n_b, n_b), m/N. mu_node: per node, the friction
    coefficient above which it is dragged into the casing, (n_b,), 1 (inf: never). mu_set:
    the same for the whole contact set (P-matrix test), 1 (inf: never). set_nodes: the
    nodes whose principal minor vanishes first at mu_set, (n_b,) 0/1. exact: whether every
    subset was tested (n_b <= 12).
    """

    rotation: int = field(metadata={"unit": "1"})
    compliance_rr: np.ndarray = field(metadata={"unit": "m/N"})
    compliance_rtheta: np.ndarray = field(metadata={"unit": "m/N"})
    mu_node: np.ndarray = field(metadata={"unit": "1"})
    mu_set: float = field(metadata={"unit": "1"})
    set_nodes: np.ndarray = field(metadata={"unit": "1"})
    exact: bool = field(default=True, metadata={"unit": "1"})

    def radial_compliance(self, mu: float) -> np.ndarray:
        """A(mu) = G_rr + s mu G_rtheta, (n_b, n_b), m/N: r = -A lam."""
        return self.compliance_rr + self.rotation * mu * self.compliance_rtheta

    def dragged_in(self, mu: float) -> np.ndarray:
        """Per node, (n_b,) bool: A_jj(mu) < 0, friction alone drags node j into the casing."""
        return np.diag(self.radial_compliance(mu)) < 0.0

    def report(self, mu: float) -> list[str]:
        """Lines of a table for the log: per node, G_rr, s G_rtheta, A_jj(mu), mu_j, verdict."""
        a = np.diag(self.radial_compliance(mu))
        lines = [f"friction lock (static, s = {self.rotation:+d}, mu = {mu:g}): r_j = -(G_rr + s mu G_rt) lam",
                 "  node   G_rr (m/N)   s G_rt (m/N)   G_rr + s mu G_rt   mu_lock   friction pushes the node"]
        grt = self.rotation * np.diag(self.compliance_rtheta)
        for j in range(len(a)):
            verdict = "INTO the casing" if a[j] < 0 else "away from the casing"
            lines.append(f"  {j:4d}  {np.diag(self.compliance_rr)[j]:11.4e}  {grt[j]:+13.4e}  {a[j]:+16.4e}  "
                         f"{self.mu_node[j]:8.3g}   {verdict}")
        nodes = ", ".join(str(j) for j in np.flatnonzero(self.set_nodes))
        bound = "" if self.exact else " (subsets of <= 12 nodes tested: an upper bound)"
        lines.append(f"  contact set: A(mu) stays a P-matrix up to mu_set = {self.mu_set:.3g}{bound}"
                     + (f" (nodes {nodes})" if nodes else ""))
        return lines

    def warnings(self, mu: float) -> list[str]:
        """Warnings for this mu: nodes dragged in, or the contact set past mu_set."""
        out = []
        bad = np.flatnonzero(self.dragged_in(mu))
        if len(bad):
            out.append(f"friction mu = {mu:g} drags contact node(s) {', '.join(map(str, bad))} into the casing "
                       f"(G_rr + s mu G_rt < 0; s = {self.rotation:+d}): once pressed there, the tip can stay locked "
                       "on the casing")
        elif mu >= self.mu_set:
            out.append(f"friction mu = {mu:g} >= mu_set = {self.mu_set:.3g}: the contact set's compliance with "
                       f"friction is not a P-matrix; several nodes in contact can wedge the blade into the casing")
        return out


def friction_lock(K: np.ndarray, n_boundary: int, rotation: int) -> FrictionLock:
    """The friction-lock table of a ROM.

    K: ROM stiffness, (n, n), N/m, the 3 n_b boundary dof first (node-major r, theta, z).
    rotation: s = +1 or -1 (rom.rotation.rotation_sign).
    """
    rotation = check_sign(rotation)
    K = np.asarray(K, dtype=float)
    if K.ndim != 2 or K.shape[0] != K.shape[1]:
        raise ValueError(f"K must be a square (n, n) ROM stiffness, got shape {K.shape}")
    if isinstance(n_boundary, (bool, np.bool_)) or not isinstance(n_boundary, (int, np.integer)) \
            or not 1 <= n_boundary <= K.shape[0] // 3:
        raise ValueError(f"n_boundary must be an integer count of contact nodes in 1..n / 3 = {K.shape[0] // 3} "
                         f"(their 3 n_b dof come first in K), got {n_boundary!r}")
    nb = int(n_boundary)
    # static compliance of the boundary dof: the inverse of the Schur complement on them
    G = np.linalg.inv(0.5 * (K + K.T))[:3 * nb, :3 * nb]
    return lock_table(G[0::3, 0::3], G[0::3, 1::3], rotation)


def lock_table(grr: np.ndarray, grt: np.ndarray, rotation: int) -> FrictionLock:
    """The lock table of any radial compliance with friction, A(mu) = G_rr + s mu G_rtheta:
    the static one (friction_lock), or an explicit time step's (hbm.ti.march.step_compliance:
    the impulse-to-displacement map of one step, whose contact problem has a unique solution
    only while its A(mu) is a P-matrix).

    grr, grt: (n_b, n_b), m/N (G_rr symmetric positive definite). rotation: s = +1 or -1.
    """
    rotation = check_sign(rotation)
    grr = np.ascontiguousarray(grr, dtype=float)
    grt = np.ascontiguousarray(grt, dtype=float)
    nb = grr.shape[0]
    sgrt = rotation * np.diag(grt)
    with np.errstate(divide="ignore"):
        mu_node = np.where(sgrt < 0.0, -np.diag(grr) / sgrt, np.inf)
    mu_set, nodes = np.inf, np.zeros(nb, dtype=np.int8)
    exact = nb <= _MAX_EXACT
    for size in range(1, min(nb, _MAX_EXACT) + 1):
        for sub in itertools.combinations(range(nb), size):
            idx = np.asarray(sub)
            mu = _first_singular_mu(grr[np.ix_(idx, idx)], rotation * grt[np.ix_(idx, idx)])
            if mu < mu_set:
                mu_set, nodes = mu, np.zeros(nb, dtype=np.int8)
                nodes[idx] = 1
    return FrictionLock(rotation=int(rotation), compliance_rr=grr, compliance_rtheta=grt, mu_node=mu_node,
                        mu_set=float(mu_set), set_nodes=nodes, exact=exact)


def _first_singular_mu(B: np.ndarray, C: np.ndarray) -> float:
    """Smallest mu > 0 with det(B + mu C) = 0, B symmetric positive definite (inf if none).

    det(B + mu C) = det(B) det(I + mu B^-1 C) vanishes at mu = -1 / lam for each real
    eigenvalue lam < 0 of B^-1 C.
    """
    lam = np.linalg.eigvals(np.linalg.solve(B, C))
    real = lam[np.abs(lam.imag) <= 1e-9 * max(1.0, np.abs(lam).max())].real
    neg = real[real < 0.0]
    return float((-1.0 / neg).min()) if len(neg) else np.inf
