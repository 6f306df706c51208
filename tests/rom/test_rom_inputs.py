"""The ROM's modal damping and options: documented ratios against an independent
eigen-solver, bad inputs refused with a clear error."""
import numpy as np
import pytest

from rom.model import modal_damping
from rom.options import RomOptions
from support import coarse_rom


def test_modal_damping_gives_the_documented_ratios_and_refuses_bad_ones():
    rom = coarse_rom()
    n = rom.n_dof
    xi = np.where(np.arange(n) < 3, 1e-3, 5e-3)
    C, w = modal_damping(rom.K, rom.M, xi)
    lam, vec = np.linalg.eig(np.linalg.solve(rom.M, rom.K))  # independent: unsymmetric solver
    phi = np.real(vec[:, np.argsort(lam.real)])
    phi /= np.sqrt(np.einsum("ij,ik,kj->j", phi, rom.M, phi))
    np.testing.assert_allclose(np.diag(phi.T @ C @ phi) / (2 * np.sqrt(np.sort(lam.real))), xi, rtol=1e-6)
    # unchecked, NaN ratios gave a NaN C, negative ones a negative damping, silently
    for bad in (np.full(n, np.nan), np.full(n, -0.01), xi[:3]):
        with pytest.raises(ValueError, match="damping ratios"):
            modal_damping(rom.K, rom.M, bad)


@pytest.mark.parametrize("kw", [dict(n_fixed_modes=12.5), dict(n_low_modes=2.5), dict(n_fixed_modes=True)])
def test_mode_counts_must_be_integers(kw):
    # unchecked, n_low_modes = 2.5 was accepted and damped 3 modes with damping_low
    with pytest.raises(ValueError, match="integer"):
        RomOptions(**kw)
    assert RomOptions(n_fixed_modes=np.int64(6)).n_fixed_modes == 6
