"""Validation mode (TI started on a periodic solution) and the sweep, on a problem whose
periodic solution with contact is exact.

One contact node (r, theta, z) on springs, casing with zero clearance (d <= 0 everywhere).
r(t) = d(Omega t) is a solution of the constrained problem as long as the force needed to
follow the casing, lam = -(m r'' + c r' + k r), is >= 0: with r = -p G, G the Gaussian lobe
of width w, lam = p G [k - c Omega 2 phi / w^2 + m Omega^2 (4 phi^2 / w^4 - 2 / w^2)] >= 0 once
k > 2 m Omega^2 / w^2 (w_r >= 9.4 Omega), true here with a margin of 3. Friction then slides
along +theta (v_z = 0, rho Omega >> v_theta) and the theta dof is a damped linear oscillator
forced by -mu lam(t), solved harmonic by harmonic. Coefficients are exact to round-off at
N_h = 100 (the Gaussian's spectrum decays as exp(-(k w)^2 / 4), e^-56 at k = 100).
"""
import math
import os
import subprocess
import sys
import time
from dataclasses import fields, replace
from pathlib import Path

import numpy as np
import pytest

from hbm.harmonic.fourier import FourierBasis
from hbm.contact.casing import casing_distance
from hbm.options import CasingOptions, ContactOptions, TimeIntegrationOptions
from hbm.ti.periodicity import PeriodClass
from hbm.ti.sweep import SpeedResponse, sweep
from hbm.ti.march import modal_system, rom_modal_system
from hbm.ti.validation import compare_with_hbm, march_from_hbm
from rom.model import modal_damping
from support import mpirun_command, needs_mpirun, standin_rom

#: The MPI sweep (tests/hbm/mpi_sweep.py runs it under mpirun; the test runs it serially).
MPI_OPTIONS = TimeIntegrationOptions(dt=1e-6, n_revolutions=6, n_keep=2, samples_per_revolution=64)
MPI_OMEGAS = np.array([1900.0, 1500.0, 1700.0])

CAS = CasingOptions(clearance=0.0, penetration=1e-4, width=0.15, n_lobes=2)
W_R, W_T, W_Z, XI, MU, RHO, THETA = 3000.0, 750.0, 1234.5, 1e-3, 0.15, 0.25, 0.2


def following_system():
    K = np.diag([W_R ** 2, W_T ** 2, W_Z ** 2])
    M = np.eye(3)
    C, _ = modal_damping(K, M, np.full(3, XI))
    return K, M, C, modal_system(K, M, C, [RHO], [THETA])


def exact_orbit(omega, n_h=100, n_fine=8192):
    """Harmonics (2 N_h + 1, 3), m, and lam(t) on n_fine instants, N, of the casing-following orbit."""
    K, M, C, _ = following_system()
    fine = FourierBasis(n_h, n_fine)
    d = casing_distance(fine.tau, np.array([THETA]), CAS)[:, 0]
    cd = fine.to_freq(d)
    D = fine.derivative_matrix
    lam_c = -(M[0, 0] * omega ** 2 * (D @ D @ cd) + C[0, 0] * omega * (D @ cd) + K[0, 0] * cd)
    lam = fine.to_time(lam_c)
    assert lam.min() >= -1e-9 * lam.max()  # the orbit is admissible: contact force >= 0
    # theta: m x'' + c x' + k x = -mu lam, harmonic by harmonic (complex form a - i b)
    k = fine.orders[1::2]
    F = -MU * (lam_c[1::2] - 1j * lam_c[2::2])
    X = F / (K[1, 1] - M[1, 1] * (k * omega) ** 2 + 1j * k * omega * C[1, 1])
    coeffs = np.zeros((2 * n_h + 1, 3))
    coeffs[:, 0] = cd
    coeffs[0, 1] = -MU * lam_c[0] / K[1, 1]
    coeffs[1::2, 1], coeffs[2::2, 1] = X.real, -X.imag
    return coeffs, lam, fine


def test_time_marching_from_the_exact_periodic_solution_stays_on_it():
    """Displacement: the multiplier puts r on the casing at every step, so TI and the exact
    orbit differ by round-off only (1e-9 allows for the truncated series of d). Force: the
    discrete multiplier is -(m delta^2 d / dt^2 + ...) = exact lam + O((dt / t_lobe)^2 d''''),
    t_lobe = w / Omega = 1.5 ms, dt ~ 2 us: ~1e-5 relative; 1e-3 is the stated bound."""
    omega = 100.0
    coeffs, lam, fine = exact_orbit(omega)
    n_t = 1024
    lam_t = lam[:: fine.n_time // n_t][:, None]
    *_, system = following_system()
    ti = march_from_hbm(system, CAS, MU, coeffs, omega, n_periods=100, dt=2e-6)
    v = compare_with_hbm(ti, coeffs, lam_t, "exact")
    assert ti.dt <= 2e-6 and ti.n_periods == 100 and ti.stays
    assert v.displacement_error.max() <= 1e-9
    assert v.force_error.max() <= 1e-3
    assert ti.drift.max() <= 1e-8 and ti.deviation.max() <= 1e-8
    assert ti.max_penetration <= 1e-18
    # a solution a quarter lobe off is not a periodic solution: the comparison must see it
    shifted = coeffs.copy()
    shifted[:, 0] = FourierBasis(100, 8192).to_freq(
        casing_distance(fine.tau + 0.05, np.array([THETA]), CAS)[:, 0])
    ti_bad = march_from_hbm(system, CAS, MU, shifted, omega, n_periods=3, dt=2e-6)
    bad = compare_with_hbm(ti_bad, shifted, lam_t, "shifted")
    assert bad.displacement_error.max() > 0.1 and ti_bad.deviation.max() > 0.1


def test_sweep_from_rest_locks_onto_the_casing():
    """From rest the node starts on the casing (d(0) ~ -p e^-110 ~ 0) and stays on it: the
    steady response is the casing itself, period T / 2 (omega = 2 Omega), amplitude exactly
    (max d - min d) / 2 = p / 2 (to round-off, since the constraint holds at every step and
    the lobe centre falls on a step: steps per revolution are a multiple of 256)."""
    *_, system = following_system()
    opts = TimeIntegrationOptions(dt=2e-6, n_revolutions=10, n_keep=4, samples_per_revolution=256)
    calls = []
    res = sweep(system, CAS, ContactOptions(mu=MU), opts, omegas=np.array([100.0, 150.0]), workers=1,
                on_point=lambda done, total: calls.append((done, total)))
    assert calls == [(1, 2), (2, 2)]
    # the radial motion and the force are periodic from the first step: the first settle test
    # (after n_keep + 2 or n_keep + 3 revolutions, one of history for the lag) stops the march
    assert (res.revolutions < opts.n_revolutions).all() and (res.transient_bound <= opts.settle_rtol).all()
    np.testing.assert_allclose(res.amplitude, CAS.penetration / 2, rtol=1e-6)
    assert (res.period_class == PeriodClass.CASING).all() and (res.period == 1).all()
    np.testing.assert_allclose(res.max_abs, CAS.penetration, rtol=1e-6)
    assert (res.dt <= 2e-6).all() and res.max_penetration.max() <= 1e-18
    assert res.times.shape == (2, 4 * 256) and res.displacement.shape == (2, 1024, 2)
    assert res.sections.shape == (2, 4 * 2 + 1, 1)
    # block means of the force keep the impulse: mean force over the window = mean lam
    coeffs, lam, _ = exact_orbit(100.0)
    assert res.normal_force[0, :, 0].mean() == pytest.approx(lam.mean(), rel=1e-3)


def test_a_speeds_time_is_its_cpu_time_not_the_time_it_waited(monkeypatch):
    """A speed marched while its process waits (beside the NFRCs' processes, on shared cores)
    records the CPU it used: a 1 s sleep inside the march adds nothing to cpu_time."""
    import hbm.ti.sweep as sweep_module

    *_, system = following_system()
    opts = TimeIntegrationOptions(dt=2e-6, n_revolutions=10, n_keep=4, samples_per_revolution=256)
    quick = sweep(system, CAS, ContactOptions(mu=MU), opts, omegas=np.array([100.0]), workers=1)
    steps = sweep_module.steps_per_revolution  # called once per speed, inside its march

    def waiting(*args, **kwargs):
        time.sleep(1.0)
        return steps(*args, **kwargs)

    monkeypatch.setattr(sweep_module, "steps_per_revolution", waiting)
    slow = sweep(system, CAS, ContactOptions(mu=MU), opts, omegas=np.array([100.0]), workers=1)
    # the march alone takes a fraction of that (the whole test, both sweeps and the 1 s sleep:
    # 1.4 s on a Zen 3 host); its compilation went to the first sweep
    assert 0 < slow.cpu_time[0] < 0.7
    assert slow.amplitude[0] == quick.amplitude[0]


def test_amplitude_is_half_the_peak_to_peak_of_the_le_radial_displacement():
    """The LE amplitude convention, the HBM's (hbm.harmonic.nfrc: (max - min) / 2), on a
    signal known at every step. With theta = 0 the node meets the lobe centre at tau = pi / 2
    and the point between lobes at tau = 0, both on steps (steps per revolution are a
    multiple of 256), and it follows the casing exactly (r = d to round-off at every step):
    max r = d(0) = -p e^{-(pi / (2 w))^2} (~ -1e-48 p), min r = d(pi / 2) = -p. Half the
    peak-to-peak is p (1 - e^{-(pi / (2 w))^2}) / 2, which no other convention gives (max |r|
    = p, the peak about the mean ~ 0.7 p, the RMS ~ 0.4 p). 1e-12: round-off of r = d."""
    *_, shifted = following_system()
    system = replace(shifted, theta=np.array([0.0]))
    opts = TimeIntegrationOptions(dt=2e-6, n_revolutions=10, n_keep=4, samples_per_revolution=256)
    res = sweep(system, CAS, ContactOptions(mu=MU), opts, omegas=np.array([100.0]), workers=1)
    d = casing_distance(np.array([0.0, np.pi / 2]), np.array([0.0]), CAS)[:, 0]
    exact = 0.5 * (d[0] - d[1])
    assert exact == pytest.approx(CAS.penetration / 2, rel=1e-40)
    assert abs(res.amplitude[0] - exact) <= 1e-12 * exact
    assert abs(res.max_abs[0] - CAS.penetration) <= 1e-12 * CAS.penetration


def test_the_te_signal_and_the_contact_share_are_the_last_nodes_radial_and_every_step():
    """Two independent nodes, the TE (last node) started where the casing is farthest out.
    Wide lobes (w = 0.6) and a clearance c = p G_e / (1 - G_e), G_e = exp(-(pi / (2 w))^2) the
    lobe's value half-way between lobes, put that farthest point at d = 0 and every other
    point inside (d < 0); the TE (theta = 0) starts there, at rest. Following the casing
    needs lam = -(m d'' + c d' + k d) > 0 at every instant (k's term inside the lobes, m's
    near the corner between them: 7e5 against 5e3 times (c + p) G at 100 rad/s), and the
    corner asks an inward impulse: the TE is on the casing at every step, r = d to round-off,
    and every step has a node in contact (share exactly 1, counted over the revolutions
    marched). The LE (theta = 0.3) starts 1 um inside the casing: the multiplier of the
    first step puts it on the casing (a plastic impact) and it follows from then on, its
    signal the casing 0.3 rad further on, not the TE's. The Poincare sections of both, at
    the casing periods, are d at the casing angle of a whole revolution."""
    w, p = 0.6, 1e-4
    g_e = math.exp(-(math.pi / (2 * w)) ** 2)
    cas = CasingOptions(clearance=p * g_e / (1 - g_e), penetration=p, width=w, n_lobes=2)
    K = np.diag([W_R ** 2, W_T ** 2, W_Z ** 2] * 2)
    M = np.eye(6)
    C, _ = modal_damping(K, M, np.full(6, XI))
    theta = np.array([0.3, 0.0])
    system = modal_system(K, M, C, [RHO, RHO], theta)
    assert casing_distance(np.array([0.0]), theta[1:], cas)[0, 0] == pytest.approx(0.0, abs=1e-20)
    opts = TimeIntegrationOptions(dt=2e-6, n_revolutions=8, n_keep=4, samples_per_revolution=256,
                                  stop_when_settled=False)
    omega = 100.0
    res = sweep(system, cas, ContactOptions(mu=MU), opts, omegas=np.array([omega]), workers=1)
    d = casing_distance(omega * res.times[0], theta, cas)  # (n_samples, 2)
    te = res.displacement[0, :, 1]
    np.testing.assert_allclose(te, d[:, 1], rtol=0, atol=1e-12 * p)
    assert np.ptp(te) > 0.5 * p  # it rides the lobes: a signal, not a dof at rest
    np.testing.assert_allclose(res.displacement[0, :, 0], d[:, 0], rtol=0, atol=1e-12 * p)
    assert np.abs(d[:, 0] - d[:, 1]).max() > 0.1 * p  # the two columns tell the nodes apart
    assert res.contact_fraction[0] == 1.0 and res.revolutions[0] == 8
    # the Poincare sections: every node at each casing period of the window, which ends on a
    # whole revolution (casing angle 0 mod pi): on the casing there, r_j = d(0, theta_j)
    sec = res.sections[0]
    assert sec.shape == (opts.n_keep * cas.n_lobes + 1, 2)
    np.testing.assert_allclose(sec, np.broadcast_to(casing_distance(np.zeros(1), theta, cas), sec.shape),
                               rtol=0, atol=1e-12 * p)


def impact_system(xi=0.01):
    """One node on stiff springs (w_r = 2000 rad/s) under lobes that dip below it (c = p =
    1e-4 m): every lobe knocks it inward, it rings down until the next. A periodic orbit of
    the casing's period, reached from rest through a transient of a few revolutions."""
    K = np.diag([2000.0 ** 2, 3000.0 ** 2, 3500.0 ** 2])
    C, _ = modal_damping(K, np.eye(3), np.full(3, xi))
    return modal_system(K, np.eye(3), C, [RHO], [THETA]), CasingOptions(clearance=1e-4, penetration=1e-4,
                                                                        width=0.3, n_lobes=2)


def test_early_stop_reports_what_the_full_run_reports():
    """Stopped once settled, the points have the class and the LE amplitude of 200 revolutions
    from rest to 1e-6: the settle bound guarantees 1e-3 (settle_rtol) at the slowest free
    decay, the impacts make the actual transient die much faster. Both systems have a known
    periodic steady state: the casing itself (following system), and the impact orbit."""
    following = following_system()[-1]
    impacts, cas_i = impact_system()
    for system, cas, om, dt in ((following, CAS, [100.0], 2e-6), (impacts, cas_i, [300.0, 700.0], 1e-6)):
        opts = TimeIntegrationOptions(dt=dt, n_revolutions=200, n_keep=20)
        early = sweep(system, cas, ContactOptions(mu=MU), opts, omegas=np.array(om), workers=1)
        full = sweep(system, cas, ContactOptions(mu=MU), replace(opts, stop_when_settled=False), omegas=np.array(om),
                     workers=1)
        assert (early.revolutions < 50).all() and (full.revolutions == 200).all()
        assert (early.contact_fraction > 0).all()
        np.testing.assert_array_equal(early.period_class, full.period_class)
        np.testing.assert_array_equal(early.period, full.period)
        np.testing.assert_allclose(early.amplitude, full.amplitude, rtol=1e-6)
        np.testing.assert_allclose(early.max_abs, full.max_abs, rtol=1e-6)


def test_a_transient_at_the_assumed_decay_is_within_settle_rtol_when_the_sweep_stops():
    """The early stop's guarantee where it is tight: the remaining transient is at most
    settle_rtol = 1e-3 (the default, README's Time integration) of the contact force's range.

    The node follows the casing (as in following_system) and is tied by a spring to an
    interior dof q (w_q = 10 Omega, xi 4e-4, the slowest free mode: tau = 40 revolutions; the
    other modes decay 3.75 to 7.5 times faster). From rest q rings down at that rate, seen only
    in the contact force. Its damped frequency is a multiple of the casing's (2 Omega), so the
    transient repeats with the orbit and shrinks by exactly rho per period: the settle test's
    bound is the transient itself, and the march stops when it has fallen to the tolerance.
    The reference is the same march run 400 revolutions (the transient left there is
    e^-7.7 of the stop's). Measured: stopped after 93 revolutions with 0.94e-3 of the range left
    (5e-3 as the tolerance: 31 revolutions, 4.5e-3 left). 1.1: between the compared instants
    a transient at exactly rho can exceed the bound by about a tenth (hbm.ti.settle)."""
    omega, w_q, k_frac = 100.0, 1000.0, 0.02
    K = np.diag([3000.0 ** 2 + k_frac * w_q ** 2, 1500.0 ** 2, 2000.0 ** 2, w_q ** 2])
    K[0, 3] = K[3, 0] = -k_frac * w_q ** 2
    C, _ = modal_damping(K, np.eye(4), np.array([4e-4, 1e-3, 1e-3, 1e-3]))
    system = modal_system(K, np.eye(4), C, [RHO], [THETA])
    assert system.slowest_decay_time() * omega / (2 * np.pi) == pytest.approx(40.0, rel=0.01)
    opts = TimeIntegrationOptions(dt=2e-6, n_keep=20)  # the default settle_rtol
    early = sweep(system, CAS, ContactOptions(mu=MU), opts, omegas=np.array([omega]), workers=1)
    ref = sweep(system, CAS, ContactOptions(mu=MU), replace(opts, n_revolutions=400, stop_when_settled=False),
                omegas=np.array([omega]), workers=1)
    f_early, f_ref = early.normal_force[0, :, 0], ref.normal_force[0, :, 0]
    left = np.abs(f_early - f_ref).max() / (f_ref.max() - f_ref.min())
    assert early.period_class[0] == ref.period_class[0] == PeriodClass.CASING
    assert 60 <= early.revolutions[0] < 200
    # within the tolerance, and the stop did not wait long past it (the bound is tight here)
    assert 0.3e-3 <= left <= 1.1e-3


def test_sweep_workers_and_serial_agree_on_the_standin_rom():
    rom = standin_rom()
    opts = TimeIntegrationOptions(dt=1e-6, n_revolutions=8, n_keep=2, samples_per_revolution=64)
    om = np.array([1900.0, 1500.0, 1700.0])
    a = sweep(rom, CasingOptions(), ContactOptions(), opts, omegas=om, workers=1)
    calls = []
    b = sweep(rom, CasingOptions(), ContactOptions(), opts, omegas=om, workers=2,
              on_point=lambda done, total: calls.append((done, total)))
    assert calls == [(1, 3), (2, 3), (3, 3)]
    np.testing.assert_array_equal(a.omega, om)
    for name in ("amplitude", "max_abs", "period_class", "displacement", "normal_force", "sections", "revolutions"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    # amplitude is (max - min) / 2 over every step of the window: at least the samples' half range
    half = 0.5 * np.ptp(a.displacement[:, :, 0], axis=1)
    assert (a.amplitude >= half).all()
    assert (a.max_abs >= np.abs(a.displacement[:, :, 0]).max(axis=1)).all()
    assert (a.contact_fraction > 0).all() and a.max_penetration.max() <= 1e-15


def test_a_sweep_started_without_cores_waits_for_them_and_ends_as_the_serial_one():
    """The runner starts the sweep beside the NFRCs with no core of its own: it must not
    compute until a core is lent, then give the serial sweep's points; cancel() ends it."""
    import time

    from hbm.ti.sweep import SweepRun

    rom = standin_rom()
    opts = TimeIntegrationOptions(dt=1e-6, n_revolutions=8, n_keep=2, samples_per_revolution=64)
    om = np.array([1900.0, 1500.0, 1700.0])
    serial = sweep(rom, CasingOptions(), ContactOptions(), opts, omegas=om, workers=1)
    run = SweepRun(rom, CasingOptions(), ContactOptions(), opts, omegas=om, workers=2, cores=0)
    time.sleep(1.0)  # one speed takes ~0.1 s here: none may have run
    assert run.done == 0
    run.lend(1)
    for _ in range(300):
        if run.done:
            break
        time.sleep(0.01)
    assert run.done >= 1
    got = run.result()
    for name in ("amplitude", "max_abs", "period_class", "displacement", "normal_force", "sections", "revolutions"):
        np.testing.assert_array_equal(getattr(got, name), getattr(serial, name))
    stopped = SweepRun(rom, CasingOptions(), ContactOptions(), opts, omegas=om, workers=2, cores=0)
    workers = list(stopped._pool._processes.values())
    stopped.cancel()
    assert stopped.done == 0 and not any(w.is_alive() for w in workers)


@pytest.mark.parametrize("workers", [1, 2])
def test_a_sweep_given_the_speeds_done_marches_only_the_others_and_ends_as_a_whole_one(workers):
    """An interrupted sweep's speeds (pipelines.stages.ti keeps them in ti.partial.h5) are not
    marched again: on_speed hears of the others only, each once, and the result is the
    uninterrupted sweep's, row for row."""
    rom = standin_rom()
    opts = TimeIntegrationOptions(dt=1e-6, n_revolutions=8, n_keep=2, samples_per_revolution=64)
    om = np.array([1900.0, 1500.0, 1700.0, 1600.0])
    whole = sweep(rom, CasingOptions(), ContactOptions(), opts, omegas=om, workers=1)
    rows = {f.name: getattr(whole, f.name) for f in fields(whole)}
    done = {i: SpeedResponse(**{k: v[i] for k, v in rows.items()}) for i in (0, 2)}
    heard, counts = [], []
    again = sweep(rom, CasingOptions(), ContactOptions(), opts, omegas=om, workers=workers, done=done,
                  on_speed=lambda i, r: heard.append((i, r.omega)), on_point=lambda n, total: counts.append(n))
    assert sorted(heard) == [(1, 1500.0), (3, 1600.0)]
    assert counts == [3, 4]  # the speeds done count from the start
    for f in fields(whole):
        if f.name != "cpu_time":
            np.testing.assert_array_equal(getattr(again, f.name), getattr(whole, f.name), err_msg=f.name)


def test_a_speed_that_cannot_be_kept_fails_the_sweep_run():
    """What on_speed raises (a full disk while keeping a speed) is the sweep's failure, not a
    line the pool logs while the sweep goes on without the speed."""
    from hbm.ti.sweep import SweepRun

    def full_disk(i, response):
        raise OSError(28, "No space left on device")

    opts = TimeIntegrationOptions(dt=1e-6, n_revolutions=8, n_keep=2, samples_per_revolution=64)
    run = SweepRun(standin_rom(), CasingOptions(), ContactOptions(), opts, omegas=np.array([1900.0, 1500.0, 1700.0]),
                   workers=2, on_speed=full_disk)
    with pytest.raises(OSError, match="No space left"):
        run.result()
    run.cancel()


def _fails_at_1500(system, casing, mu, omega, options):
    """hbm.ti.sweep.simulate, but a speed of 1500 rad/s raises (a worker's failure)."""
    from hbm.ti.sweep import SpeedResponse

    if omega == 1500.0:
        raise FloatingPointError("the march at 1500 rad/s diverged")
    return SpeedResponse(*(0.0,) * 18)


def test_a_speed_that_fails_in_a_sweep_run_is_raised_when_it_is_waited_for(monkeypatch):
    import hbm.ti.sweep as sweep_module

    monkeypatch.setattr(sweep_module, "simulate", _fails_at_1500)  # before the pool forks its workers
    opts = TimeIntegrationOptions(dt=1e-6, n_revolutions=8, n_keep=2, samples_per_revolution=64)
    run = sweep_module.SweepRun(standin_rom(), CasingOptions(), ContactOptions(), opts,
                                omegas=np.array([1900.0, 1500.0, 1700.0]), workers=2, cores=1)
    with pytest.raises(FloatingPointError, match="at 1500 rad/s diverged"):
        run.result()
    run.cancel()


def _killed_at_1900(system, casing, mu, omega, options):
    """hbm.ti.sweep.simulate (a stand-in's response), but the worker marching 1900 rad/s is
    killed (SIGKILL: the OOM killer's signal)."""
    import signal

    if omega == 1900.0:
        os.kill(os.getpid(), signal.SIGKILL)
    return SpeedResponse(*(0.0,) * 18)


def test_a_killed_worker_fails_the_sweep_with_a_line_that_says_so(monkeypatch):
    """Python's BrokenProcessPool names nothing and reads as a bug (the CLI shows a traceback
    for it); the sweep raises hbm.processes.WorkerDied instead, and keeps what it finished."""
    import hbm.ti.sweep as sweep_module
    from hbm.processes import WorkerDied

    monkeypatch.setattr(sweep_module, "simulate", _killed_at_1900)
    kept = []
    opts = TimeIntegrationOptions(dt=1e-6, n_revolutions=8, n_keep=2, samples_per_revolution=64)
    run = sweep_module.SweepRun(standin_rom(), CasingOptions(), ContactOptions(), opts,
                                omegas=np.array([1900.0, 1500.0, 1700.0]), workers=1,
                                on_speed=lambda i, r: kept.append(i))
    with pytest.raises(WorkerDied, match="worker process of the time-integration sweep ended without an answer "
                       r"\(killed, perhaps for lack of memory\); speeds being marched: 1900 rad/s$"):
        run.result()
    run.cancel()
    assert sorted(kept) == [1, 2]  # one worker, slowest first: 1500 and 1700 rad/s ended before


@needs_mpirun
def test_mpi_sweep_equals_the_serial_one(tmp_path):
    """`mpirun -n 2` splits the points over two ranks (hbm.processes.mpi_world); every rank
    gets the whole result, equal to the serial sweep's to the bit (same points, same code).
    Both start from the same ModalSystem arrays: the eigen-decomposition itself differs at
    round-off with the BLAS thread count, which mpirun's process binding changes."""
    import mpi4py  # noqa: F401  (installed with python3-dolfinx; a missing one must fail, not skip)
    system = rom_modal_system(standin_rom())
    np.savez(tmp_path / "system.npz", **{f.name: getattr(system, f.name) for f in fields(system)
                                         if getattr(system, f.name) is not None})
    out = tmp_path / "mpi.npz"
    cmd, env = mpirun_command(Path(__file__).resolve().parents[2])
    run = subprocess.run(cmd + [sys.executable, str(Path(__file__).with_name("mpi_sweep.py")),
                                str(tmp_path / "system.npz"), str(out)],
                         env=env, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stdout + run.stderr
    got = np.load(out)
    serial = sweep(system, CasingOptions(), ContactOptions(), MPI_OPTIONS, omegas=MPI_OMEGAS, workers=1)
    assert list(got["ranks"]) == [2, 2]  # both ranks saw a communicator of size 2
    for name in ("omega", "amplitude", "period_class", "revolutions", "displacement", "normal_force", "sections"):
        np.testing.assert_array_equal(got[name], getattr(serial, name))


@needs_mpirun
def test_a_failing_rank_ends_the_mpi_sweep_on_every_rank(tmp_path):
    """A speed that fails on one rank (here: keeping it, as on a full disk) raises there and
    as RankFailed naming it on the other rank, which would otherwise wait for it forever in
    the sweep's gathering of the results (the timeout turns such a hang into a failure)."""
    system = rom_modal_system(standin_rom())
    np.savez(tmp_path / "system.npz", **{f.name: getattr(system, f.name) for f in fields(system)
                                         if getattr(system, f.name) is not None})
    cmd, env = mpirun_command(Path(__file__).resolve().parents[2])
    run = subprocess.run(cmd + [sys.executable, str(Path(__file__).with_name("mpi_sweep.py")),
                                str(tmp_path / "system.npz"), str(tmp_path / "mpi.npz"), "fail"],
                         env=env, capture_output=True, text=True, timeout=300)
    assert run.returncode != 0
    # (mpirun forwards each rank's lines as they come: they may run together)
    out = run.stdout
    assert out.count(" raised ") == 2, out + run.stderr
    assert ("rank 0 raised RankFailed: rank 1 failed in the time-integration sweep: OSError: [Errno 28] No space "
            "left on device") in out, out + run.stderr
    assert "rank 1 raised OSError: [Errno 28] No space left on device" in out, out + run.stderr


def test_sweep_refuses_an_unstable_time_step():
    with pytest.raises(ValueError, match="dt_crit"):
        sweep(standin_rom(), CasingOptions(), ContactOptions(), TimeIntegrationOptions(scheme="carpenter", dt=1e-4),
              omegas=[1000.0])


def test_the_modal_system_is_the_same_whatever_the_blas_threads():
    """The sweep's modal system (and its massless model) from the coarse rotor 67 ROM is the
    same to the bit with one BLAS thread and with two: a threaded eigh moved the modes by
    ~1e-13 (phi^T M by 7e-12), which the sweep's chaotic speeds amplify into other final
    states, so the same ROM gave another sweep on a machine with more cores or under taskset.
    threadpoolctl starts the second thread on a one-core machine too (under `taskset -c 0`
    a threaded eigh of this ROM still differs from one thread's), so this runs everywhere."""
    from threadpoolctl import threadpool_limits

    from hbm.ti.march import massless_system
    from support import coarse_rom

    rom = coarse_rom()
    systems = []
    for threads in (2, 1):
        with threadpool_limits(limits=threads, user_api="blas"):
            full = rom_modal_system(rom)
            systems.append((full, massless_system(full, 3.0 * full.omega[0])))
    (a, am), (b, bm) = systems
    for name in ("omega", "phi", "phi_t_m", "damping"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert np.array_equal(am.residual, bm.residual)


def test_a_window_too_short_to_classify_is_refused_before_the_march():
    """One revolution of a one-lobe casing is 2 Poincare sections: no period can be seen
    twice. Refused at once, by name, not after the first revolutions with the classifier's
    own message."""
    from hbm.ti.sweep import simulate

    opts = TimeIntegrationOptions(n_revolutions=4, n_keep=1)
    with pytest.raises(ValueError, match=r"n_keep = 1 revolutions of a casing with 1 lobe\(s\) give 2 Poincare "
                                         r"sections; the periodicity class needs at least 3"):
        simulate(rom_modal_system(standin_rom()), CasingOptions(n_lobes=1), 0.1, 1000.0, opts)
    # two lobes: 3 sections, classified
    r = simulate(rom_modal_system(standin_rom()), CasingOptions(n_lobes=2), 0.1, 1000.0, opts)
    assert r.revolutions == 4
