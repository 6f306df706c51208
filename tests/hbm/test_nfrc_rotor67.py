"""NFRC on the coarse rotor 67 ROM (tests/data/rotor67_coarse_rom.h5): resume and conventions.

Small settings (N_h = 5, N_t = 64, a 100 rad/s window from 400 rad/s where DLFT starts from
the contact-free solution) keep each test to a few seconds; the default-size NFRC is a
benchmark (benchmarks/bench_hbm.py), not a test.
"""
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from hbm.branch_store import BranchStore, load_branch, partial_path
from hbm.nfrc import compute_nfrc, default_continuation
from hbm.options import CasingOptions, ContactOptions, HbmOptions

ROM_PATH = Path(__file__).resolve().parents[1] / "data" / "rotor67_coarse_rom.h5"
HBM = HbmOptions(n_harmonics=5, n_time=64, omega_start=400.0, omega_end=500.0)
CONT = replace(default_continuation(HBM), ds=0.02, ds_max=0.05, max_points=25)


@pytest.fixture(scope="module")
def rom():
    from rom.model import load_rom
    return load_rom(ROM_PATH)


class Stop(Exception):
    pass


def test_resume_equals_uninterrupted_run(rom, tmp_path):
    """Interrupt after k points (exception in on_point), reload the partial file, resume:
    the points must be those of an uninterrupted run. The computation is deterministic
    and the resumed run rebuilds the step length from the stored step and iterations, so
    the comparison is to round-off (rtol 1e-9 on omega and x; the LU reuse statistics may
    differ, whence not bit-identical: Newton's last iterate agrees to ~ tol_residual = 1e-8
    in scaled units, 1e-7 absolute on x ~ 1 leaves margin)."""
    full = compute_nfrc(rom, CasingOptions(), ContactOptions(), HBM, "dlft", continuation=CONT)
    assert full.converged[0] and len(full.omega) >= 8, full.status
    k = 5
    path = tmp_path / "nfrc.h5"
    holder = {}

    def writer(stop_after=None):
        def on_point(point, extras):
            if "store" not in holder:
                holder["store"] = BranchStore.create(path, len(point.x))
            holder["store"].append(point, extras)
            if stop_after is not None and holder["store"].n_points >= stop_after:
                raise Stop
        return on_point

    with pytest.raises(Stop):
        compute_nfrc(rom, CasingOptions(), ContactOptions(), HBM, "dlft", continuation=CONT,
                     on_point=writer(stop_after=k))
    holder.pop("store").close()
    saved = load_branch(partial_path(path), allow_partial=True)
    assert len(saved.branch) == k and not saved.complete
    np.testing.assert_allclose(saved.extras["le_amplitude"], full.le_amplitude[:k], rtol=1e-12)
    holder["store"] = BranchStore.reopen(partial_path(path))
    resumed = compute_nfrc(rom, CasingOptions(), ContactOptions(), HBM, "dlft", continuation=CONT,
                           on_point=writer(), resume=saved)
    final = holder.pop("store").finalize(resumed.status)
    assert resumed.status == full.status and resumed.start == "resumed"
    assert len(resumed.omega) == len(full.omega)
    np.testing.assert_allclose(resumed.omega, full.omega, rtol=1e-9)
    np.testing.assert_allclose(resumed.unknowns, full.unknowns, rtol=1e-9, atol=1e-7)
    np.testing.assert_allclose(resumed.le_amplitude, full.le_amplitude, rtol=1e-7)
    stored = load_branch(final)
    assert stored.complete and len(stored.branch) == len(full.omega)
    np.testing.assert_allclose(stored.extras["le_amplitude"], full.le_amplitude, rtol=1e-7)


def test_le_amplitude_is_half_peak_to_peak(rom):
    """le_amplitude = (max - min) / 2 of the LE radial signal on a fine grid (N_t = 4096
    resamples the same N_h harmonics; the AFT grid of 64 samples misses the extrema by
    at most O((pi N_h / N_t)^2) relative, < 6 % here, so a 10 % tolerance)."""
    r = compute_nfrc(rom, CasingOptions(), ContactOptions(), HBM, "dlft",
                     continuation=replace(CONT, max_points=3))
    from hbm.aft import FourierBasis
    sig = FourierBasis(HBM.n_harmonics, 4096).to_time(r.harmonics[0][:, 0])
    assert r.le_amplitude[0] == pytest.approx(0.5 * (sig.max() - sig.min()), rel=0.1)
    assert r.le_max[0] == pytest.approx(sig.max(), rel=0.1)
