"""The friction-lock table (rom.friction_lock) with each contact force spread over a patch of
the tip surface, against the point force the ROM applies, on meshes of one blade at several
sizes: does mu_set converge with the mesh once the contact acts through a patch?

A point force on a continuum has no converged static compliance (the displacement under it
grows without bound as the mesh is refined), so the ROM's G_rr at a contact node, and with it
mu_j = -G_rr,jj / (s G_rtheta,jj) and mu_set, follow the tip's mesh (README, *Rotation
sense*). Here the force on node j is a traction over the tip facets (mesh.h5's tip_facets,
tri6) with a cone profile max(0, 1 - d / a) of the distance d to node j, a the patch radius,
in node j's local r or theta direction; its consistent nodal loads f come from the tri6 shape
functions, integrated on each facet's 4^4 sub-triangles (flat facets), and are normalised to a
unit resultant. The displacement paired with it is the work-conjugate mean f^T u. Then

    G_rr[j, k] = f_r(j)^T K^-1 f_r(k),   G_rtheta[j, k] = f_r(j)^T K^-1 f_theta(k)   (m/N),

from the full model's K (fem.h5, one Cholesky factorisation for every radius), and
rom.friction_lock.lock_table gives mu_j and mu_set. a = 0 is the point force: it must give
rom.h5's own table (printed as a check: the Craig-Bampton ROM's static compliance at its
boundary dof is the full model's).

Usage:
  PYTHONPATH=. .venv/bin/python benchmarks/bench_tip_patch.py OUT [OUT ...] [--radii 0,3e-3,6e-3,12e-3] [--node 6]

OUT: output folders with mesh.h5, fem.h5 and rom.h5 of one blade meshed at several sizes.
Prints per folder and radius mu_set, the set's nodes, and node `--node`'s G_rr, s G_rtheta and
mu_j, with the factorisation's and solves' time.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from fem.cholesky import CholeskyFactor  # noqa: E402
from pipelines.stages.fem import read_fem  # noqa: E402
from pipelines.stages.mesh import read_mesh  # noqa: E402
from pipelines.stages.rom import read_rom  # noqa: E402
from rom.friction_lock import lock_table  # noqa: E402

#: sub-triangle levels of each facet's quadrature (4^LEVELS sub-triangles, their centroids):
#: the cone's kink at d = a then errs by ~(h / 2^LEVELS)^2 of a facet's load, h its size.
LEVELS = 4


def _subtriangle_centroids(levels: int) -> tuple[np.ndarray, np.ndarray]:
    """Barycentric centroids (m, 3) of the 4^levels congruent sub-triangles of the reference
    triangle, and their weights (m,) (each 1 / m of the area)."""
    tris = [np.eye(3)]
    for _ in range(levels):
        nxt = []
        for t in tris:
            a, b, c = t
            ab, bc, ca = (a + b) / 2, (b + c) / 2, (c + a) / 2
            nxt += [np.array(x) for x in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))]
        tris = nxt
    cent = np.array([t.mean(axis=0) for t in tris])
    return cent, np.full(len(cent), 1.0 / len(cent))


def _tri6_shapes(bary: np.ndarray) -> np.ndarray:
    """tri6 shape functions (m, 6) at barycentric points (m, 3), gmsh order (3 vertices, then
    edges 01, 12, 20)."""
    l0, l1, l2 = bary.T
    return np.stack([l0 * (2 * l0 - 1), l1 * (2 * l1 - 1), l2 * (2 * l2 - 1), 4 * l0 * l1, 4 * l1 * l2, 4 * l2 * l0], 1)


def patch_weights(nodes: np.ndarray, facets: np.ndarray, centre: np.ndarray, radius: float) -> dict[int, float]:
    """Consistent nodal weights of a cone traction max(0, 1 - |x - centre| / radius) on the
    tri6 facets (n_f, 6), normalised to sum 1; {mesh node: weight}. radius 0: the node at
    `centre` alone."""
    if radius == 0.0:
        return {int(np.argmin(np.linalg.norm(nodes - centre, axis=1))): 1.0}
    bary, w = _subtriangle_centroids(LEVELS)
    N = _tri6_shapes(bary)  # (m, 6)
    out: dict[int, float] = {}
    for f in facets:
        x = nodes[f]  # (6, 3)
        if np.min(np.linalg.norm(x[:3] - centre, axis=1)) > radius + np.max(np.linalg.norm(x[:3] - x[[1, 2, 0]], axis=1)):
            continue
        area = 0.5 * np.linalg.norm(np.cross(x[1] - x[0], x[2] - x[0]))
        q = bary @ x[:3]  # quadrature points on the flat facet (m, 3)
        t = np.maximum(0.0, 1.0 - np.linalg.norm(q - centre, axis=1) / radius)
        if not t.any():
            continue
        f_loc = area * (N * (w * t)[:, None]).sum(axis=0)
        for i, v in zip(f, f_loc):
            out[int(i)] = out.get(int(i), 0.0) + float(v)
    total = sum(out.values())
    if total <= 0.0:
        raise ValueError(f"no tip facet within {radius:g} m of {centre}")
    return {i: v / total for i, v in out.items()}


def load_vector(n_free: int, node_dofs: np.ndarray, weights: dict[int, float], direction: np.ndarray) -> np.ndarray:
    """(n_free,) nodal loads of a unit resultant along `direction` (3,) with these weights;
    the clamped dof (node_dofs -1) take none."""
    f = np.zeros(n_free)
    for i, v in weights.items():
        d = node_dofs[i]
        keep = d >= 0
        f[d[keep]] += v * direction[keep]
    return f


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("outs", nargs="+")
    ap.add_argument("--radii", default="0,3e-3,6e-3,12e-3", help="patch radii a, m (0: the point force)")
    ap.add_argument("--node", type=int, default=6, help="the contact node whose compliances are printed")
    a = ap.parse_args()
    radii = [float(x) for x in a.radii.split(",")]
    print("| mesh | nodes | a (mm) | mu_set | set nodes | node G_rr (m/N) | node s G_rtheta (m/N) | node mu_j | nodes loaded (min-max) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for out in map(Path, a.outs):
        mesh, fem, rom = read_mesh(out), read_fem(out), read_rom(out)
        s = int(rom.friction_lock.rotation)
        t0 = time.perf_counter()
        factor = CholeskyFactor(fem.K)
        t_factor = time.perf_counter() - t0
        n_free = fem.K.shape[0]
        cols, spans = [], []
        for r in radii:
            for j, c in enumerate(mesh.boundary_node_index):
                wts = patch_weights(mesh.nodes, mesh.tip_facets, mesh.nodes[c], r)
                spans.append(len(wts))
                cols += [load_vector(n_free, fem.node_dofs, wts, mesh.boundary_frames[j, 0]),
                         load_vector(n_free, fem.node_dofs, wts, mesh.boundary_frames[j, 1])]
        F = np.stack(cols, axis=1)
        t0 = time.perf_counter()
        U = factor.solve(F)
        t_solve = time.perf_counter() - t0
        nb = len(mesh.boundary_node_index)
        for ir, r in enumerate(radii):
            Fr = F[:, 2 * nb * ir: 2 * nb * (ir + 1): 2]
            Ur, Ut = U[:, 2 * nb * ir: 2 * nb * (ir + 1): 2], U[:, 2 * nb * ir + 1: 2 * nb * (ir + 1): 2]
            grr, grt = Fr.T @ Ur, Fr.T @ Ut
            lock = lock_table(0.5 * (grr + grr.T), grt, s)
            j = a.node
            set_nodes = ",".join(map(str, np.flatnonzero(lock.set_nodes)))
            n_loaded = spans[nb * ir: nb * (ir + 1)]
            print(f"| {out.name} | {len(mesh.nodes)} | {1e3 * r:g} | {lock.mu_set:.3f} | {set_nodes} | {grr[j, j]:.4e} | "
                  f"{s * grt[j, j]:+.4e} | {lock.mu_node[j]:.3f} | {min(n_loaded)}-{max(n_loaded)} |", flush=True)
            if r == 0.0:
                ref = rom.friction_lock
                dev = max(np.abs(lock.compliance_rr - ref.compliance_rr).max() / np.abs(ref.compliance_rr).max(),
                          np.abs(lock.compliance_rtheta - ref.compliance_rtheta).max()
                          / np.abs(ref.compliance_rtheta).max())
                print(f"|  | check: point force against rom.h5's table: largest relative difference {dev:.1e}, "
                      f"mu_set {ref.mu_set:.3f} |  |  |  |  |  |  |  |")
        print(f"|  | factorisation {t_factor:.1f} s, {F.shape[1]} solves {t_solve:.1f} s |  |  |  |  |  |  |  |", flush=True)
        factor.destroy()


if __name__ == "__main__":
    main()
