"""A complex per-point extra in a branch file: its rows without a value hold nan."""
from __future__ import annotations

import numpy as np

from hbm.continuation.branch import ContinuationPoint
from pipelines.branch_store import BranchStore, load_branch


def test_a_resume_that_starts_recording_a_complex_extra_fills_the_earlier_rows_with_nan(tmp_path):
    """Rows 0-1, written before the extra existed, read nan in both parts (h5py refuses a
    float nan as a complex dataset's fill value); rows 2-3 hold what was appended."""
    pts = [ContinuationPoint(i, 1.0 + i, np.full(3, float(i)), True, 0.0, 1, 0.1, 0.0) for i in range(4)]
    path = tmp_path / "nfrc.h5"
    with BranchStore.create(path, 3) as store:
        for p in pts[:2]:
            store.append(p, {"a": 1.0})
    store = BranchStore.reopen(path)
    for p in pts[2:]:
        store.append(p, {"a": 1.0, "multiplier": np.complex128(0.5 - 2.0j)})
    store.finalize("reached omega_max")
    mu = load_branch(path).extras["multiplier"]
    assert mu.dtype == np.complex128
    assert np.isnan(mu[:2].real).all() and np.isnan(mu[:2].imag).all()
    assert mu[2:].tolist() == [0.5 - 2.0j, 0.5 - 2.0j]
