"""NFRC on the coarse rotor 67 ROM (tests/data/rotor67_coarse_rom.h5): resume and conventions.

Small settings (N_h = 5, N_t = 64, a 100 rad/s window from 400 rad/s where DLFT starts from
the contact-free solution) keep each test to a few seconds; the default-size NFRC is a
benchmark (benchmarks/bench_hbm.py), not a test.
"""
from dataclasses import replace

import numpy as np
import pytest

from pipelines.branch_store import BranchStore, load_branch, partial_path
from hbm.harmonic.nfrc import compute_nfrc, default_continuation
from hbm.options import CasingOptions, ContactOptions, HbmOptions
from support import coarse_rom, distance_to_polyline

HBM = HbmOptions(n_harmonics=5, n_time=64, omega_min=400.0, omega_max=500.0)
CONT = replace(default_continuation(HBM), direction=1, ds=0.02, ds_max=0.05, max_points=25)  # from 400 rad/s


@pytest.fixture(scope="module")
def rom():
    return coarse_rom()


class Stop(Exception):
    pass


def test_resume_equals_uninterrupted_run(rom, tmp_path):
    """Interrupt after k points (exception in on_point), reload the partial file, resume:
    the k stored points are kept bit for bit and the resumed run follows the branch of an
    uninterrupted one to the end. Not at the same arc lengths to round-off: the GMRES
    solver's reused preconditioner is not stored, and its last Newton step is solved
    only to what Newton's test needs (an absolute 1e-9 on the scaled residual), so the
    converged points differ at Newton's tolerance and the step sequences drift apart
    (measured: omega within 1.1e-6 relative over the 25 points). What must hold: every
    resumed point on the uninterrupted polyline in the continuation's metric (u, omega /
    100) to 1e-3 of a step (measured 1.4e-4: Newton's tolerance seen through J^-1; a point
    of another sheet or a skipped fold is a step or more away)."""
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
    np.testing.assert_array_equal(resumed.unknowns[:k], saved.branch.x)
    assert abs(len(resumed.omega) - len(full.omega)) <= 1
    pa = np.column_stack([full.unknowns, full.omega / 100.0])
    pb = np.column_stack([resumed.unknowns, resumed.omega / 100.0])
    step = np.median(np.linalg.norm(np.diff(pa, axis=0), axis=1))
    assert distance_to_polyline(pb, pa).max() < 1e-3 * step
    stored = load_branch(final)
    assert stored.complete and len(stored.branch) == len(resumed.omega)
    np.testing.assert_allclose(stored.extras["le_amplitude"], resumed.le_amplitude, rtol=1e-12)


def test_le_amplitude_is_half_peak_to_peak(rom):
    """le_amplitude = (max - min) / 2 of the LE radial displacement on the AFT grid (the
    convention of the time-integration side), exactly: the signal is summed here directly
    from its cosine and sine coefficients at tau_i = 2 pi i / N_t (no FFT)."""
    r = compute_nfrc(rom, CasingOptions(), ContactOptions(), HBM, "dlft",
                     continuation=replace(CONT, max_points=3))
    for h, amp, top in zip(r.harmonics, r.le_amplitude, r.le_max):
        c = h[:, 0]  # LE radial dof: [c0, a1, b1, ..., a_Nh, b_Nh]
        tau = 2 * np.pi * np.arange(HBM.n_time) / HBM.n_time
        k = np.arange(1, HBM.n_harmonics + 1)
        sig = c[0] + np.cos(np.outer(tau, k)) @ c[1::2] + np.sin(np.outer(tau, k)) @ c[2::2]
        assert amp == pytest.approx(0.5 * (sig.max() - sig.min()), rel=1e-12, abs=0)
        assert top == pytest.approx(sig.max(), rel=1e-12, abs=0)


# -- primary resonance (2 Omega ~ omega_1B) ------------------------------------------------
# Neither method starts from the contact-free solution inside [1290, 1400] rad/s; a cheap
# N_h = 5 branch continued from 2000 rad/s (where both start) down to 1400 gives a start
# guess, padded with zero harmonics to N_h = 10. The 1290-1400 window holds the peak of the
# primary resonance at N_h = 10 (RL ~1.73 mm at ~1311 rad/s, DLFT ~1.58 mm at ~1326 rad/s,
# the same values as the whole NFRC continued from 2000 rad/s at N_h = 10).
LOW = HbmOptions(n_harmonics=5, n_time=64, omega_min=1400.0, omega_max=2000.0)
PEAK = HbmOptions(n_harmonics=10, n_time=256, omega_min=1290.0, omega_max=1400.0)


def _peak_branch(rom, method):
    low = compute_nfrc(rom, CasingOptions(), ContactOptions(), LOW, method,
                       continuation=default_continuation(LOW))
    assert low.status == "reached omega_min" and low.omega[-1] == 1400.0, low.status
    return compute_nfrc(rom, CasingOptions(), ContactOptions(), PEAK, method,
                        continuation=default_continuation(PEAK),
                        guess=(1400.0, low.unknowns[-1]))


@pytest.fixture(scope="module")
def peak_branches(rom):
    return {m: _peak_branch(rom, m) for m in ("dlft", "rl")}


def test_primary_resonance_dlft_rl_agree(peak_branches):
    """Both methods cross the window (1400 -> 1290 rad/s) and peak inside it.

    Tolerances: the two laws differ at N_h = 10 by construction, not by a bug: RL filters
    its contact force with the Lanczos sigma, sigma_2 = sinc(2 / 11) = 0.947 on the
    resonant second harmonic (a ~5 % weaker contact at resonance), and lets the tip into
    the casing by lambda / kappa (~30 um at the ~30 kN peak force, kappa = 1e9 N/m),
    while DLFT enforces the gap only in the N_h-harmonic sense. Measured at N_h = 10:
    1.733 vs 1.584 mm (9 %), 1311 vs 1326 rad/s (1.1 %); at N_h = 20 (N_t = 512) they close in,
    1.743 vs 1.686 mm (3 %), 1325 vs 1332 rad/s, as the two laws converge together. Hence 15 % on the peak
    amplitude (a wrong branch, e.g. the low sheet at ~0.5 mm, or a missed resonance
    fails it by far) and 3 % on the peak speed (the resonance is ~60 rad/s wide at
    half height, so 3 % ~ 40 rad/s still pins it)."""
    peaks = {}
    for m, r in peak_branches.items():
        assert r.status == "reached omega_min" and r.converged.all(), (m, r.status)
        assert r.start.startswith("damped Newton from the guess"), r.start
        i = int(np.argmax(r.le_amplitude))
        assert 1290.0 < r.omega[i] < 1400.0, (m, r.omega[i])
        peaks[m] = (r.omega[i], r.le_amplitude[i])
    (w_d, a_d), (w_r, a_r) = peaks["dlft"], peaks["rl"]
    assert 1.2e-3 < a_d < 2.5e-3 and 1.2e-3 < a_r < 2.5e-3, peaks  # the high sheet (Fig. 6 scale)
    assert abs(a_d - a_r) <= 0.15 * max(a_d, a_r), peaks
    assert abs(w_d - w_r) <= 0.03 * max(w_d, w_r), peaks


def test_primary_resonance_dlft_solution_and_contact(rom, peak_branches):
    """At the DLFT peak: the residual of a freshly built residual is at the continuation's
    tolerance; lambda >= 0; and the penetration is the DLFT Gibbs ripple, no more.

    The last check uses eq. (15) independently of the solver path: with P_N the
    projection on the N_h harmonics (FFT of the samples), the solution satisfies
    P_N lambda = (f - Z x)_r, so lambda_pre = P_N lambda + eps g and lambda = max(0,
    lambda_pre); hence eps g = lambda - P_N lambda where lambda > 0 (the penetration is
    the truncation ripple of the force divided by eps) and eps g <= -P_N lambda where
    lambda = 0. Both to 1e-6 of max lambda (round-off of the FFTs and the 1e-8 residual
    tolerance, which is ~1e-8 k_ref / alpha ~ 1e-3 N on the force)."""
    from hbm.harmonic.residual import build_residual
    r = peak_branches["dlft"]
    i = int(np.argmax(r.le_amplitude))
    u, w = r.unknowns[i], r.omega[i]
    res = build_residual(rom, CasingOptions(), ContactOptions(), PEAK, method="dlft")
    assert np.linalg.norm(res(u, w, jacobian=False)) <= default_continuation(PEAK).newton.tol_residual
    s = res.signals(u, w)
    lam, gap = s["lam"], s["gap"]  # (N_t, n_b), N and m
    assert lam.min() >= 0.0 and lam.max() > 0.0  # in contact at the peak
    b = res.basis
    proj = b.to_time(b.to_freq(lam))  # P_N lambda
    eps, tol = ContactOptions().epsilon, 1e-6 * lam.max()
    on = lam > 0.0
    np.testing.assert_allclose(eps * gap[on], (lam - proj)[on], atol=tol, rtol=0)
    assert np.all(eps * gap[~on] <= -proj[~on] + tol)
