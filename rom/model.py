"""The reduced-order model as the nonlinear stages see it (plain numpy, no PETSc)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rom.friction_lock import FrictionLock
from rom.rotation import check_sign


@dataclass(frozen=True)
class RomModel:
    """Craig-Bampton reduced model, n = 3 n_b + eta dof.

    Dof order: the n_b boundary nodes first, node-major, each in its local cylindrical
    frame (r, theta, z): [r_1, t_1, z_1, r_2, ..., z_nb], then the eta fixed-interface
    modal coordinates. Node 0 is the leading edge (LE), node n_b - 1 the trailing edge.

    K: stiffness, (n, n), N/m. M: mass, (n, n), kg. C: viscous damping, (n, n), N s/m.
    rho: radius of each boundary node from the rotation axis (z), (n_b,), m.
    theta: angular position of each boundary node, relative to the LE node, (n_b,), rad.
    xyz: boundary node coordinates, (n_b, 3), m.
    frames: local frames, (n_b, 3, 3), rows e_r, e_theta, e_z in global x, y, z.
    node_index: mesh node index of each boundary node, (n_b,).
    fixed_interface_frequencies: (eta,), rad/s. frequencies: ROM eigenfrequencies, (n,), rad/s.
    full_frequencies: the full model's first eigenfrequencies, rad/s (for comparison).
    damping_ratios: modal damping ratio of each ROM mode, (n,).
    rotation: sense of rotation s = +1 or -1 (right-hand rule about z): node j sits at the
        absolute angle s Omega t + theta_j and its tip moves at s rho_j Omega along e_theta
        (rom.rotation). The nonlinear stages take it from here and never assume it.
    friction_lock: the static friction-lock table (rom.friction_lock), None when not computed.
    recovery: full-field displacement of each ROM dof, (3 n_nodes, n), m per unit of the
        ROM dof (global x, y, z, node-major); None when not stored.
    """

    K: np.ndarray = field(metadata={"unit": "N/m"})
    M: np.ndarray = field(metadata={"unit": "kg"})
    C: np.ndarray = field(metadata={"unit": "N*s/m"})
    rho: np.ndarray = field(metadata={"unit": "m"})
    theta: np.ndarray = field(metadata={"unit": "rad"})
    xyz: np.ndarray = field(metadata={"unit": "m"})
    frames: np.ndarray = field(metadata={"unit": "1"})
    node_index: np.ndarray = field(metadata={"unit": "1"})
    fixed_interface_frequencies: np.ndarray = field(metadata={"unit": "rad/s"})
    frequencies: np.ndarray = field(metadata={"unit": "rad/s"})
    full_frequencies: np.ndarray = field(metadata={"unit": "rad/s"})
    damping_ratios: np.ndarray = field(metadata={"unit": "1"})
    rotation: int = field(metadata={"unit": "1"})
    friction_lock: FrictionLock | None = None
    recovery: np.ndarray | None = field(default=None, metadata={"unit": "m"})

    def __post_init__(self):
        """Refuse inconsistent or non-finite data with a message naming the field (a foreign
        or corrupt rom.h5 fails here, not deep in the nonlinear stages). Cheap: shapes,
        finiteness, symmetry and one Cholesky of M, no eigen-solve."""
        object.__setattr__(self, "rotation", check_sign(self.rotation))
        n = check_pencil(self.K, self.M)
        check_matrix("C", self.C, n)
        rho = _check_array("rho", self.rho, (np.size(self.rho),), "n_b, one radius per boundary node")
        nb = len(rho)
        if nb == 0 or rho.min() <= 0.0:
            raise ValueError(f"rho must hold n_b >= 1 radii > 0 m, got {rho!r}")
        if 3 * nb > n:
            raise ValueError(f"rho has n_b = {nb} boundary nodes, 3 n_b = {3 * nb} dof, but K has only n = {n}")
        nodes = f"n_b = {nb} boundary nodes, from rho"
        _check_array("theta", self.theta, (nb,), nodes)
        _check_array("xyz", self.xyz, (nb, 3), nodes)
        check_frames("frames", self.frames, nb)
        index = _check_array("node_index", self.node_index, (nb,), nodes, lower=0)
        if not np.issubdtype(index.dtype, np.integer):
            raise ValueError(f"node_index must hold integer mesh node indices, got dtype {index.dtype}")
        eta = n - 3 * nb
        _check_array("fixed_interface_frequencies", self.fixed_interface_frequencies, (eta,),
                     f"eta = n - 3 n_b = {n} - 3 x {nb}", lower=0.0)
        _check_array("frequencies", self.frequencies, (n,), "n, one per ROM mode", lower=0.0)
        _check_array("damping_ratios", self.damping_ratios, (n,), "n, one per ROM mode", lower=0.0)
        full = np.asarray(self.full_frequencies)
        _check_array("full_frequencies", full, (full.size,), "one dimension", lower=0.0)
        if self.friction_lock is not None:
            for name in ("compliance_rr", "compliance_rtheta"):
                _check_array(f"friction_lock.{name}", getattr(self.friction_lock, name), (nb, nb), nodes)
        if self.recovery is not None:
            shape = np.shape(self.recovery)  # shape only: its (3 n_nodes, n) entries are too many to scan each time
            if len(shape) != 2 or shape[0] % 3 or shape[1] != n:
                raise ValueError(f"recovery must have shape (3 n_nodes, n = {n}), got {shape}")

    @property
    def n_boundary(self) -> int:
        return int(len(self.rho))

    @property
    def n_dof(self) -> int:
        return int(self.K.shape[0])

    @property
    def nonlinear_dofs(self) -> np.ndarray:
        """Indices of the 3 n_b boundary (nonlinear) dof."""
        return np.arange(3 * self.n_boundary)


#: Symmetry tolerance of K, M, C: that of the HBM condensation (hbm.harmonic.condensation),
#: so that a RomModel the ROM accepts is one the nonlinear side accepts.
_SYMMETRY_RTOL, _SYMMETRY_ATOL = 1e-10, 1e-12


def _check_array(name: str, value, shape: tuple, meaning: str, lower: float | None = None) -> np.ndarray:
    """value as an array, after checking its shape, that it is finite and (lower given) >= lower;
    raises ValueError naming `name`, the expected shape and its `meaning`."""
    a = np.asarray(value)
    if a.shape != shape:
        raise ValueError(f"{name} must have shape {shape} ({meaning}), got {a.shape}")
    if not np.issubdtype(a.dtype, np.number) or np.iscomplexobj(a):
        raise ValueError(f"{name} must be real numbers, got dtype {a.dtype}")
    bad = ~np.isfinite(a)
    if bad.any():
        raise ValueError(f"{name} has {int(bad.sum())} NaN or inf entries, the first at index "
                         f"{tuple(int(i) for i in np.argwhere(bad)[0])}")
    if lower is not None and a.size and a.min() < lower:
        raise ValueError(f"{name} must be >= {lower}, got {a.min()!r} at index "
                         f"{tuple(int(i) for i in np.unravel_index(a.argmin(), a.shape))}")
    return a


def check_matrix(name: str, A, n: int) -> np.ndarray:
    """A as an (n, n) real, finite, symmetric array (to round-off: _SYMMETRY_RTOL); raises
    ValueError naming `name` and what is wrong."""
    A = _check_array(name, A, (n, n), "n x n, n = 3 n_b + eta from K")
    scale = float(np.abs(A).max()) if A.size else 0.0
    if not np.allclose(A, A.T, rtol=_SYMMETRY_RTOL, atol=_SYMMETRY_ATOL * scale):
        raise ValueError(f"{name} is not symmetric: max |{name} - {name}^T| = {np.abs(A - A.T).max():.3e}, "
                         f"max |{name}| = {scale:.3e} (relative tolerance {_SYMMETRY_RTOL:g})")
    return A


def check_pencil(K, M) -> int:
    """n after checking K and M as (n, n) finite symmetric matrices, M positive definite (one
    Cholesky); raises ValueError naming the matrix. K's semi-definiteness needs an eigen-solve:
    eigenfrequencies checks it."""
    shape = np.shape(K)
    if len(shape) != 2 or shape[0] != shape[1] or shape[0] == 0:
        raise ValueError(f"K must be a square (n, n) matrix, n = 3 n_b + eta, got shape {shape}")
    n = shape[0]
    check_matrix("K", K, n)
    M = check_matrix("M", M, n)
    try:
        np.linalg.cholesky(M)
    except np.linalg.LinAlgError:
        raise ValueError(f"M is not positive definite (its Cholesky factorisation fails; smallest "
                         f"diagonal entry {np.diag(M).min():.3e} kg): not a mass matrix") from None
    return n


def eigenfrequencies(K: np.ndarray, M: np.ndarray, vectors: bool = False):
    """Eigenfrequencies w of (K, M), (n,), rad/s, ascending; with vectors, (w, phi), phi
    (n, n) M-orthonormal.

    K, M: (n, n), N/m and kg (check_pencil). A negative eigenvalue w^2 is round-off, and
    taken as 0, down to -n eps cond(M) max|w^2|: eigh reduces (K, M) with the Cholesky factor
    of M, whose eigenvalue error is about eps ||K|| ||M^-1|| <= eps cond(M) max|w^2| (Golub &
    Van Loan, the symmetric-definite problem), with n for the accumulation over n terms; on the
    coarse rotor 67 ROM (cond(M) = 2.9e6) that is 2.5e-8 max|w^2|, 60 times below its first w^2.
    Below it, ValueError: K is indefinite, and a zero frequency with zero damping would hide it.
    """
    import scipy.linalg

    check_pencil(K, M)
    out = scipy.linalg.eigh(K, M, eigvals_only=not vectors)
    w2 = out[0] if vectors else out
    m = np.linalg.eigvalsh(M)
    tol = len(w2) * np.finfo(float).eps * (m[-1] / m[0]) * float(np.abs(w2).max())
    if w2[0] < -tol:
        raise ValueError(f"K is not positive semi-definite: (K, M) has the eigenvalue w^2 = {w2[0]:.6g} rad^2/s^2, "
                         f"below the round-off bound -{tol:.3g} (n eps cond(M) max|w^2|); the ROM is not a "
                         f"clamped, stable structure or K is corrupt")
    w = np.sqrt(np.clip(w2, 0.0, None))
    return (w, out[1]) if vectors else w


def check_frames(name: str, frames, nb: int) -> np.ndarray:
    """frames as an (n_b, 3, 3) array of right-handed orthonormal frames (rows e_r, e_theta,
    e_z, to 1e-8; e_r x e_theta = e_z); raises ValueError naming `name`. A left-handed frame
    (e_theta or e_z flipped) is orthonormal too, and would turn the friction force and the
    friction-lock table the wrong way without a word."""
    frames = _check_array(name, frames, (nb, 3, 3), f"n_b = {nb} boundary nodes, rows e_r, e_theta, e_z")
    if not np.allclose(frames @ frames.transpose(0, 2, 1), np.eye(3), atol=1e-8):
        raise ValueError(f"{name} must be orthonormal (rows e_r, e_theta, e_z)")
    left = np.flatnonzero(np.linalg.det(frames) < 0.0)
    if left.size:
        raise ValueError(f"{name} must be right-handed (e_r x e_theta = e_z); the frames of boundary nodes "
                         f"{left.tolist()} are left-handed")
    return frames


def modal_damping(K: np.ndarray, M: np.ndarray, ratios: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Damping matrix C = M Phi diag(2 xi_k w_k) Phi^T M from modal ratios.

    K: (n, n) symmetric positive semi-definite, N/m. M: (n, n) symmetric positive definite,
    kg. ratios: (n,) xi_k in ascending frequency order. Returns (C, w) with w the
    eigenfrequencies, rad/s (eigenfrequencies: ValueError when K is indefinite).
    """
    w, phi = eigenfrequencies(K, M, vectors=True)
    xi = np.asarray(ratios, dtype=float)
    if xi.ndim == 0:  # one ratio for every mode
        xi = np.full(w.shape, float(xi))
    if xi.shape != w.shape or not np.all(np.isfinite(xi)) or np.any(xi < 0.0):
        raise ValueError(f"ratios must be {len(w)} finite damping ratios >= 0 (one per mode), got {ratios!r}")
    mp = M @ phi  # phi is M-orthonormal
    C = mp @ np.diag(2.0 * xi * w) @ mp.T
    return 0.5 * (C + C.T), w


def load_rom(path, with_recovery: bool = False) -> RomModel:
    """Read a rom.h5 artifact (layout of RomModel, one dataset per field) with h5py only.

    with_recovery: also read the (3 n_nodes, n) recovery matrix (large on fine meshes).
    """
    import dataclasses
    from pathlib import Path

    import h5py

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"ROM file not found: {path}")
    kw = {}
    with h5py.File(path, "r") as h5:
        for f in dataclasses.fields(RomModel):
            if f.name == "recovery" and not with_recovery:
                continue
            if f.name == "friction_lock" and f.name in h5:
                g = h5[f.name]
                kw[f.name] = FrictionLock(**{k: g[k][()] if k in g else g.attrs[k] for k in
                                             (ff.name for ff in dataclasses.fields(FrictionLock))})
            elif f.name in h5:
                kw[f.name] = h5[f.name][()]
            elif f.default is dataclasses.MISSING:
                raise ValueError(f"{path} is not a ROM file: dataset '{f.name}' is missing")
    try:
        return RomModel(**kw)
    except ValueError as e:
        raise ValueError(f"{path}: {e}") from e
