"""isolas.h5 says what its content columns are: whose modes (rom.h5's, with their frequencies
beside them) and which frequency a harmonic column is (k Omega / nu). Without it, a reader of
the file alone could not tell the ROM's modes from the full model's, nor harmonic k of Omega
from harmonic k of Omega / 2."""
import h5py
import numpy as np

from hbm.isolas.search import FoundBranch
from pipelines.stages.isolas import _write_branch, read_isolas


def test_content_columns_carry_their_meaning_and_the_mode_frequencies(tmp_path):
    m, n, nh = 4, 6, 3
    fb = FoundBranch(omega=np.linspace(500.0, 510.0, m), x=np.zeros((m, 9)), converged=np.ones(m, bool),
                     kind="isola", closed=True, status="closed", start=0, seeds=(0,),
                     extras={"le_amplitude": np.full(m, 1e-4), "harmonics": np.zeros((m, 2 * nh + 1, 3))})
    freq = np.array([100.0, 250.0, 600.0, 900.0, 1500.0, 2100.0])
    content = {"modal_contribution": np.full((m, n), 1.0 / n), "harmonic_contribution": np.ones((m, nh + 1)),
               "mode_frequencies": freq}
    with h5py.File(tmp_path / "isolas.h5", "w") as h5:
        _write_branch(h5.create_group("dlft/branches/000"), fb, 2, content)
    with h5py.File(tmp_path / "isolas.h5") as h5:
        b = h5["dlft/branches/000"]
        assert "rom.h5" in b["modal_contribution"].attrs["description"]
        assert "modes/frequencies" in b["modal_contribution"].attrs["description"]
        assert "k Omega / nu" in b["harmonic_contribution"].attrs["description"]
        np.testing.assert_array_equal(b["modes/frequencies"][()], freq)
        assert b["modes/frequencies"].attrs["unit"] == "rad/s" and b.attrs["subharmonic"] == 2
    (branch,) = read_isolas(tmp_path / "isolas.h5")["dlft"]
    np.testing.assert_array_equal(branch.modal_contribution, content["modal_contribution"])
