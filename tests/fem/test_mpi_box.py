"""FEM stage on 2 MPI ranks against one process, on a small box where one rank holds every
contact node and the other none (both ways round).

tests/pipelines/test_mpi.py compares the ranks on a blade, where each rank's share of the
contact nodes is whatever the mesh numbering gives; here the rank without a contact dof is
forced (mpi_box.renumbered): the interface basis's boundary rows, the constraint modes'
identity block and the fixed-interface solve's held dof then all live on one rank.
"""
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from support import mpirun_command, needs_mpirun

ROOT = Path(__file__).resolve().parents[2]
pytestmark = needs_mpirun


@pytest.mark.parametrize("arrangement, holder", [("first", 0), ("last", 1)])
def test_two_ranks_match_one_process_when_a_rank_holds_no_contact_node(tmp_path, arrangement, holder):
    out = tmp_path / "r.npz"
    words, env = mpirun_command(ROOT)
    proc = subprocess.run(words + [sys.executable, str(Path(__file__).with_name("mpi_box.py")), arrangement,
                                   str(out)], cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    r = np.load(out)
    held = r["contact_dof_per_rank"]
    assert held[holder] == 9 and held[1 - holder] == 0, held  # 3 contact nodes, all on `holder`
    for name in ("K", "M"):
        for part in ("indptr", "indices"):  # the same pattern in the serial numbering
            np.testing.assert_array_equal(r[f"par_{name}_{part}"], r[f"ser_{name}_{part}"], err_msg=name)
        # the same element matrices, summed in another order where the partitions meet: ulps
        d = r[f"ser_{name}_data"]
        np.testing.assert_allclose(r[f"par_{name}_data"], d, rtol=0, atol=1e-14 * abs(d).max(), err_msg=name)
    for name in ("frequencies", "fixed_interface_frequencies"):
        np.testing.assert_allclose(r[f"par_{name}"], r[f"ser_{name}"], rtol=1e-9, err_msg=name)
    for name in ("modes", "constraint_modes", "fixed_interface_modes"):
        # same iteration and sign rule (fem.modes): round-off apart, measured ~5e-13
        b = r[f"ser_{name}"]
        assert r[f"par_{name}"].shape == b.shape, name
        np.testing.assert_allclose(r[f"par_{name}"], b, rtol=0, atol=1e-8 * abs(b).max(), err_msg=name)
    assert (r["par_residuals"] < 1e-2).all() and (r["ser_residuals"] < 1e-2).all()
