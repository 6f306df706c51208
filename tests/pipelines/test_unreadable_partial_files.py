"""A partial file that HDF5 cannot open (a run killed while writing its first bytes, a copy
cut short): the stage says so, names the file and HDF5's reason, and starts over; it used to
start over without a word, as from a file of other inputs, and the user saw a resumable run
take its whole time again. The run ends with exit 0 and the artifact a run without the
file gives.
"""
import h5py
import numpy as np
import pytest

from coarse_runs import clone
from pipelines import artifacts as art
from pipelines.branch_store import load_branch
from pipelines.cli import main


def _cut(path, like):
    """`path` made of the first half of the HDF5 file `like` (its superblock says more)."""
    data = like.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(OSError):
        h5py.File(path, "r")


def _warnings(err: str) -> list:
    return [line for line in err.splitlines() if line.startswith("bladerub: warning: ") and "cannot be read" in line]


@pytest.mark.parametrize("until, partial, says", [
    ("hbm", "nfrc_dlft.partial.h5", "the dlft NFRC starts over"),
    ("ti", "ti.partial.h5", "its speeds are marched again"),
    ("isolas", "isolas.partial.h5", "the search starts over"),
])
def test_a_cut_partial_file_is_named_and_the_stage_starts_over(coarse_nfrc, tmp_path, capsys, until, partial, says):
    out = tmp_path / "out"
    scene = clone(coarse_nfrc[1], out)
    if until == "hbm":
        (out / "nfrc_dlft.h5").unlink()  # the link: the NFRC is to be computed again
    _cut(out / partial, coarse_nfrc[1] / "nfrc_dlft.h5")
    assert main(["run", str(scene), "--out", str(out), "--until", until, "--quiet"]) == 0
    found = _warnings(capsys.readouterr().err)
    assert len(found) == 1, found
    assert found[0].startswith(f"bladerub: warning: {partial} cannot be read (") and found[0].endswith(f"): {says}")
    assert "truncated" in found[0]  # HDF5's own reason (its superblock's end of file lies past the cut)
    final = {"hbm": "nfrc_dlft.h5", "ti": "ti.h5", "isolas": "isolas.h5"}[until]
    assert art.verify(out / final) is None and not (out / partial).exists()
    if until == "hbm":  # the NFRC of a run that never had the file
        np.testing.assert_array_equal(load_branch(out / final).branch.omega,
                                      load_branch(coarse_nfrc[1] / "nfrc_dlft.h5").branch.omega)
