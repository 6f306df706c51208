"""Test support: small models with the layout of the real artifacts."""
from __future__ import annotations

import dataclasses
import functools
import os
import shutil

import numpy as np
import pytest

from rom.model import RomModel, modal_damping


def standin_rom(n_boundary: int = 9, n_modes: int = 12, seed: int = 0, rotation: int = 1) -> RomModel:
    """A 39-dof stand-in with the RomModel layout and rotor-67-like orders of magnitude
    (rotation: its sense s, +1 or -1).

    Not a blade: K, M come from prescribed eigenfrequencies and random M-orthonormal
    shapes, so tests written against it exercise the shapes and code paths only.
    """
    rng = np.random.default_rng(seed)
    n = 3 * n_boundary + n_modes
    w = np.concatenate([[1050.0, 2900.0, 4300.0], np.linspace(6500.0, 60000.0, n - 3)])  # rad/s
    q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    m = 0.05  # kg per dof
    M = m * (np.eye(n) + 0.1 * np.diag(rng.random(n)))
    L = np.linalg.cholesky(M)
    phi = np.linalg.solve(L.T, q)  # M-orthonormal
    Mphi = M @ phi
    K = Mphi @ np.diag(w ** 2) @ Mphi.T
    K = 0.5 * (K + K.T)
    ratios = np.where(np.arange(n) < 3, 1e-3, 5e-3)
    C, wr = modal_damping(K, M, ratios)
    theta = np.linspace(0.0, 0.35, n_boundary)
    rho = np.full(n_boundary, 0.2427)
    xyz = np.stack([rho * np.cos(theta), rho * np.sin(theta), np.linspace(-0.03, 0.03, n_boundary)], 1)
    frames = np.stack([np.stack([np.cos(theta), np.sin(theta), 0 * theta], 1),
                       np.stack([-np.sin(theta), np.cos(theta), 0 * theta], 1),
                       np.tile([0.0, 0.0, 1.0], (n_boundary, 1))], 1)
    return RomModel(K=K, M=M, C=C, rho=rho, theta=theta, xyz=xyz, frames=frames,
                    node_index=np.arange(n_boundary), fixed_interface_frequencies=w[3 * n_boundary:],
                    frequencies=wr, full_frequencies=wr[:6], damping_ratios=ratios,
                    rotation=rotation)


def mirrored_rom(rom: RomModel) -> tuple[RomModel, np.ndarray]:
    """(the mirror image of rom through a meridian plane turning the other way, p): each
    contact node's theta_j -> -theta_j and its tangential dof -> its negative (K, M, C ->
    P K P, ..., P = diag(p)), rotation -> -rotation; p: (n_dof,), +-1, maps a state of one
    onto the other. The same physical problem seen in a mirror (tests of the sense)."""
    p = np.ones(rom.n_dof)
    p[1:3 * rom.n_boundary:3] = -1.0
    P = np.diag(p)
    return dataclasses.replace(rom, K=P @ rom.K @ P, M=P @ rom.M @ P, C=P @ rom.C @ P, theta=-rom.theta,
                               rotation=-rom.rotation), p

# The shared data folder beside the repository (CI clones main with ../shared beside it):
# the one way tests find it.
from pathlib import Path as _Path

SHARED = _Path(__file__).resolve().parents[2] / "shared"
#: The coarse rotor 67 ROM the rotor 67 tests share (tests/data/README.md says how it was built).
COARSE_ROM = _Path(__file__).resolve().parent / "data" / "rotor67_coarse_rom.h5"
#: rotor 67's NASA table, and the coarse scenes' mesh settings (8 mm, one element across the
#: edges: ~24 000 nodes, a few seconds to mesh)
R67_TABLE = SHARED / "data" / "rotor67" / "rotor67geometry.dat"
COARSE_MESH = dict(element_size=0.008, edge_layers=1, size_growth=0.5)


def coarse_rom() -> RomModel:
    """The coarse rotor 67 ROM (COARSE_ROM), loaded afresh (tests may not share one object)."""
    from rom.model import load_rom

    return load_rom(COARSE_ROM)


@functools.lru_cache(maxsize=1)
def coarse_dlft_nfrc():
    """(rom, casing, contact, residual, NFRCResult): the coarse ROM's DLFT NFRC at the scene's resolution (N_h = 40,
    N_t = 1024, default casing and contact), 2000 down to 1334 rad/s, without stability
    (~11 s), computed once per test process for the tests that look at its 1334-1470 rad/s
    stretch. Tests only read it."""
    from hbm.harmonic.nfrc import compute_nfrc
    from hbm.harmonic.residual import build_residual
    from hbm.options import CasingOptions, ContactOptions, HbmOptions

    rom = coarse_rom()
    casing, contact = CasingOptions(), ContactOptions()
    opts = HbmOptions(n_harmonics=40, n_time=1024, omega_min=1334.0, omega_max=2000.0)
    r = compute_nfrc(rom, casing, contact, opts, "dlft", stability=False)
    assert r.status == "reached omega_min", r.status
    return rom, casing, contact, build_residual(rom, casing, contact, opts, method="dlft"), r


def distance_to_polyline(points: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Distance of each point to the polyline through `poly`, (k,), for points (k, d) and
    poly (s, d) in one metric (e.g. the continuation's scaled (u, omega / 100))."""
    seg = np.diff(poly, axis=0)
    rel = points[:, None] - poly[None, :-1]
    t = np.clip(np.einsum("ksn,sn->ks", rel, seg) / np.einsum("sn,sn->s", seg, seg), 0.0, 1.0)
    return np.linalg.norm(rel - t[..., None] * seg[None], axis=2).min(axis=1)


def coarse_text() -> str:
    """The coarse rotor 67 scene's text with the shared data folder made absolute and two
    mode pictures instead of six."""
    text = (_Path(__file__).resolve().parents[1] / "scenes" / "rotor67_coarse.toml").read_text()
    return text.replace("../../shared", str(SHARED)).replace("n_modes = 6", "n_modes = 2")


def fresh_copy(src, dst):
    """A private copy of an output folder (artifacts and figures), for a test that changes it."""
    import shutil

    shutil.copytree(src, dst, dirs_exist_ok=True)
    return _Path(dst)


def shell_env() -> dict:
    """The environment of a command started from a shell, to pass as env=: os.environ, the
    environment this process started with, less any MPI launcher variables (OMPI_*, PMIX_*).
    Passing it matters: the singleton MPI environment that dolfinx's MPI_Init adds lives in
    the C environment only, and a child started with env=None inherits it and joins this
    process's MPI job as its rank 0."""
    return {k: v for k, v in os.environ.items() if not k.startswith(("OMPI_", "PMIX_"))}


#: The MPI tests need Open MPI's launcher (.ci/install installs it): where it is missing they cannot run.
needs_mpirun = pytest.mark.skipif(shutil.which("mpirun") is None,
                                  reason="mpirun not found (Debian: openmpi-bin, installed by .ci/install)")


def mpirun_command(root, n: int = 2) -> tuple[list, dict]:
    """(`mpirun -n N` words, environment with the checkout `root` and tests/ on the path); as
    root, with the flags Open MPI needs to run there and on N slots of a smaller machine.
    The environment is shell_env()'s: mpirun must start a job of its own, not join this
    process's singleton one."""
    env = dict(shell_env(), PYTHONPATH=f"{root}{os.pathsep}{os.path.join(root, 'tests')}")
    return ["mpirun", "-n", str(n)] + (["--allow-run-as-root", "--oversubscribe"] if os.geteuid() == 0 else []), env


def unit_search_options(*, max_points: int, ds_max: float, newton_tol: float = 1e-12, seed_iterations: int = 30,
                        tolerance: float = 1e-2, ds: float = 0.05, omega_max: float = 1.0):
    """hbm.isolas.search.SearchOptions for the scalar test systems on omega in [0, omega_max],
    x ~ 1 (unit scales, one worker): continuation steps of ds up to ds_max, max_points per
    direction, Newton to newton_tol (seeds with a line search, seed_iterations at most)."""
    from hbm.continuation.arclength import ContinuationOptions
    from hbm.continuation.newton import NewtonOptions
    from hbm.isolas.search import SearchOptions

    co = ContinuationOptions(omega_min=0.0, omega_max=omega_max, ds=ds, ds_min=1e-6, ds_max=ds_max, x_scale=1.0,
                             omega_scale=1.0, max_points=max_points, closed_loop_tol=1e-3,
                             newton=NewtonOptions(tol_residual=newton_tol, max_iter=12))
    return SearchOptions(tolerance=tolerance, continuation=co, workers=1,
                         newton=NewtonOptions(tol_residual=newton_tol, max_iter=seed_iterations, line_search=True))


def forced_standin_residual(method: str = "dlft", n_harmonics: int = 8, n_time: int = 128, rotation: int = 1,
                            **contact):
    """The HBM residual of standin_rom(rotation=rotation) forced at engine order 2 on a
    boundary dof and a modal dof (50 and 20 N: dR/domega has a force part), contact options
    from `contact` (e.g. mu=0.15). With perturbed_state, a state in contact part of the period."""
    from hbm.harmonic.condensation import HarmonicForcing
    from hbm.harmonic.residual import build_residual
    from hbm.options import CasingOptions, ContactOptions, HbmOptions

    rom = standin_rom(rotation=rotation)
    f = np.zeros(rom.n_dof)
    f[[0, 30]] = [50.0, 20.0]
    return build_residual(rom, CasingOptions(), ContactOptions(**contact),
                          HbmOptions(n_harmonics=n_harmonics, n_time=n_time), method=method,
                          forcing=HarmonicForcing(f, 2))


def perturbed_state(res, seed: int = 3, omega: float = 900.0) -> np.ndarray:
    """The linear solution at omega (rad/s) plus a random 0.3 in every scaled unknown: on
    the stand-in, several nodes in contact part of the period, (n_u,)."""
    return res.linear_solution(omega) + 0.3 * np.random.default_rng(seed).standard_normal(res.size)
