"""A point whose stability is unknown (n_unstable -1) says why in the files: the NFRC files
(pipelines.branch_store, the hbm stage's per-point extras) and isolas.h5 carry a per-point
text `stability_note`, "" where a verdict is known.

The monitor is fed spectra given in closed form (stable multipliers 0.5 and 0.3), except at
points 9 to 12, whose analyses have no multiplier left (every family dropped): with
max_gap 8 it analyses 0, 1, 9, 10, 11 (no verdict), cuts the chain there and hands on
2..8 without a count (NOT_INFERRED), 9..12 with their analyses' reason, and the rest with
a verdict (as tests/hbm/test_stability_incomplete.py establishes for the monitor alone).
"""

import h5py
import numpy as np

from hbm.continuation.branch import ContinuationPoint
from hbm.isolas.search import FoundBranch
from hbm.stability.monitor import NOT_INFERRED, StabilityMonitor, StabilityOptions, monitor_branch
from hbm.stability.spectrum import FloquetSpectrum
from pipelines.artifacts import verify
from pipelines.branch_store import BranchStore, load_branch
from pipelines.stages import isolas as stage

OMEGA = 1000.0
WHY = "no eigenvector inside the harmonic band (too few harmonics)"
N = 30
EXPECTED = [""] * 2 + [NOT_INFERRED] * 7 + [WHY] * 4 + [""] * (N - 13)


def _spectrum(mu) -> FloquetSpectrum:
    mu = np.asarray(mu, complex)
    k = len(mu)
    return FloquetSpectrum(omega=OMEGA, exponents=np.log(mu) * OMEGA / (2 * np.pi) if k else np.zeros(0, complex),
                           multipliers=mu, centred=np.ones(k, bool), edge_energy=np.zeros(k),
                           eigenvectors=np.zeros((k, 3, 2), complex), modulus_floor=0.05 if k else 1.0,
                           method="arnoldi", note="" if k else WHY)


def _analyse(x, w):
    return _spectrum([] if 9 <= int(x[0]) <= 12 else [0.5, 0.3]), 1


def test_the_nfrc_file_says_why_a_point_has_no_verdict(tmp_path):
    mon = StabilityMonitor(analyse=_analyse, options=StabilityOptions(max_gap=8))
    store = BranchStore.create(tmp_path / "nfrc_dlft.h5", 1)
    done = []

    def put(out):
        for p, ex in out:
            store.append(p, ex)
            done.append(p.index)

    for i in range(N):
        put(mon.push(ContinuationPoint(i, OMEGA - i, np.array([float(i)]), True, 0.0, 1, 1.0, 0.0),
                     {"le_amplitude": 1e-4 * i}))
    put(mon.finish())
    assert done == list(range(N))
    path = store.finalize("reached omega_min")
    assert verify(path) is None  # the text column is covered by the checksums
    got = load_branch(path).extras
    assert got["stability_note"].tolist() == EXPECTED
    assert (got["n_unstable"] == -1).tolist() == [bool(n) for n in EXPECTED]
    with h5py.File(path) as h5:
        assert h5py.check_string_dtype(h5["extras/stability_note"].dtype) is not None


def test_a_resumed_nfrc_file_of_an_earlier_version_reads_its_old_points_as_without_note(tmp_path):
    store = BranchStore.create(tmp_path / "nfrc_rl.h5", 1)
    for i in range(3):  # an earlier version: no stability_note
        store.append(ContinuationPoint(i, OMEGA - i, np.zeros(1), True, 0.0, 1, 1.0, 0.0), {"n_unstable": 0})
    store.close()
    store = BranchStore.reopen(tmp_path / "nfrc_rl.h5")
    store.append(ContinuationPoint(3, OMEGA - 3, np.zeros(1), True, 0.0, 1, 1.0, 0.0),
                 {"n_unstable": -1, "stability_note": NOT_INFERRED})
    got = load_branch(store.finalize("done")).extras
    assert got["stability_note"].tolist() == ["", "", "", NOT_INFERRED]
    assert got["n_unstable"].tolist() == [0, 0, 0, -1]


def test_isolas_h5_says_why_a_point_has_no_verdict(tmp_path):
    omega = OMEGA - np.arange(N, dtype=float)
    x = np.arange(N, dtype=float)[:, None]
    st = monitor_branch(_analyse, omega, x, [{"le_amplitude": 1e-4 * i} for i in range(N)],
                        options=StabilityOptions(max_gap=8))
    fb = FoundBranch(omega=omega, x=x, converged=np.ones(N, bool), kind="isola", closed=True, status="closed",
                     start=0, seeds=(0,), extras={"le_amplitude": 1e-4 * np.arange(N),
                                                   "harmonics": np.zeros((N, 3, 2)), **st.per_point()})
    with h5py.File(tmp_path / "isolas.h5", "w") as h5:
        stage._write_branch(h5.create_group("dlft/branches/000"), fb, 1)
    (b,) = stage.read_isolas(tmp_path / "isolas.h5")["dlft"]
    assert b.stability_note.tolist() == EXPECTED
    assert (b.n_unstable == -1).tolist() == [bool(n) for n in EXPECTED]
    with h5py.File(tmp_path / "isolas.h5") as h5:  # a resume reads it back as written
        back = stage._read_found(h5["dlft/branches/000"])
    assert back.extras["stability_note"].tolist() == EXPECTED
