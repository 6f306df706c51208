"""Modal contributions (eqs. 32-33) from the ROM against the full finite-element model.

The Craig-Bampton boundary dof are displacements, not modal coordinates: content.py takes
gamma_j = Phi_j^T M_rom x with the ROM's own modes. With the ROM's basis T (fem.h5's
constraint modes in the boundary nodes' frames, then its fixed-interface modes), that is
exactly the projection of the recovered full field T x on T Phi_j with the full mass matrix;
against the full model's own modes (fem.h5 `modes`) it is as close as the ROM's modes are
to them. On the coarse rotor 67 run of the session (coarse_run: fem.h5, rom.h5), for a
motion of the ROM made mostly of its first four modes on several harmonics."""

import numpy as np


def _dense_peaks(coeffs, n=1 << 16):
    """max_t |g| of the signals with harmonics coeffs (2 N_h + 1, m), eq. (5) order, from n samples."""
    nh = (len(coeffs) - 1) // 2
    tau = 2 * np.pi * np.arange(n) / n
    k = np.arange(1, nh + 1)
    g = coeffs[0] + np.cos(np.outer(tau, k)) @ coeffs[1::2] + np.sin(np.outer(tau, k)) @ coeffs[2::2]
    return np.abs(g).max(axis=0)


def test_rom_modal_contributions_against_the_full_model(coarse_run):
    import h5py
    import scipy.sparse as sp

    from hbm.harmonic.content import modal_contributions_of_harmonics, rom_modes
    from rom.model import load_rom

    run = coarse_run[1]
    rom = load_rom(run / "rom.h5")
    with h5py.File(run / "fem.h5") as f:
        g = f["M"]
        Mf = sp.csr_matrix((g["data"][()], g["indices"][()], g["indptr"][()]), shape=tuple(g.attrs["shape"]))
        free = f["node_dofs"][()].ravel() >= 0
        modes = f["modes"][()]
        psi, fixed = f["constraint_modes"][()], f["fixed_interface_modes"][()]
    nb = rom.n_boundary
    R = np.zeros((3 * nb, 3 * nb))
    for j in range(nb):
        R[3 * j:3 * j + 3, 3 * j:3 * j + 3] = rom.frames[j].T  # local (r, theta, z) -> global x, y, z
    T = np.hstack([psi @ R, fixed[:, :rom.K.shape[0] - 3 * nb]])  # the ROM's basis, (n_free, n)
    np.testing.assert_allclose(T.T @ (Mf @ T), rom.M, atol=1e-12 * abs(rom.M).max())  # the ROM's M is T^T M T

    w, phi = rom_modes(rom.K, rom.M)
    # harmonics 0..10 of a motion in the ROM's modal coordinates, m: modes 1-4 of order 1e-4 m,
    # the others 1e-2 of that (an orbit near the first resonances, as Fig. 11's)
    rng = np.random.default_rng(0)
    q = 1e-6 * rng.standard_normal((21, phi.shape[1]))
    q[:, :4] *= 100.0
    coeffs = q @ phi.T  # (2 N_h + 1, n) ROM dof
    content = modal_contributions_of_harmonics(coeffs, rom.M, phi)

    X = T @ coeffs.T  # the recovered full field, (n_free, 2 N_h + 1), m
    MX = Mf @ X
    ritz = _dense_peaks(MX.T @ (T @ phi))  # on the ROM's Ritz vectors T Phi_j, full M
    # exact but for the samples: 2^16 a period miss the peak of harmonic 10 by far less than 2e-6
    np.testing.assert_allclose(content, ritz / ritz.sum(), rtol=0, atol=2e-6)

    Phi = modes.reshape(len(modes), -1)[:, free].T  # the full model's modes, (n_free, 12), mass-normalised
    np.testing.assert_allclose(Phi.T @ (Mf @ Phi), np.eye(Phi.shape[1]), atol=1e-8)
    mac = (Phi.T @ (Mf @ (T @ phi[:, :4]))) ** 2  # Phi and T phi both mass-normalised
    assert np.all(np.diag(mac[:4]) > 0.99)  # ROM mode j is full mode j for 1B, 2B, 1T, 4th
    full = _dense_peaks(MX.T @ Phi)
    # the first four (Fig. 11's): peaks within 0.5 % (at a DLFT isola point, 495 rad/s: 2e-6, 3e-4, 7e-4, 3.5e-3),
    # contributions with the full model's modes in the ROM's denominator within 2e-4 (seen 7e-5)
    np.testing.assert_allclose(full[:4], ritz[:4], rtol=5e-3)
    np.testing.assert_allclose(full[:4] / ritz.sum(), content[:4], rtol=0, atol=2e-4)
