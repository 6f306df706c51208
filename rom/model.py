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
        object.__setattr__(self, "rotation", check_sign(self.rotation))

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


def modal_damping(K: np.ndarray, M: np.ndarray, ratios: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Damping matrix C = M Phi diag(2 xi_k w_k) Phi^T M from modal ratios.

    K, M: (n, n) symmetric, M positive definite. ratios: (n,) xi_k in ascending
    frequency order. Returns (C, w) with w the eigenfrequencies, rad/s.
    """
    import scipy.linalg

    w2, phi = scipy.linalg.eigh(K, M)
    w = np.sqrt(np.clip(w2, 0.0, None))
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
    return RomModel(**kw)
