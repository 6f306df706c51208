"""Time-integration frequency sweep (section 3.1 and Fig. 5 of the reference paper).

For each rotation speed Omega: at most n_revolutions revolutions from null initial
conditions, the last n_keep kept for the leading-edge (LE) amplitude, the periodicity class
and the downsampled LE/TE signals. The march stops earlier once the response has provably
settled on a periodic orbit (hbm.ti.settle: the window's remaining transient is below
settle_rtol); the window is then the last n_keep revolutions marched. Points run in
parallel: over MPI ranks when launched under mpirun (communicator size > 1), otherwise over a
local process pool (all cores by default).

The time step is shrunk from dt to dt_eff = T / N <= dt, N the smallest multiple of
lcm(n_l SUBSECTIONS, samples_per_revolution) with N >= T / dt: revolutions, casing periods,
the settle test's instants and output samples then fall on steps, so no signal needs
interpolation, and dt_eff stays stable.

Amplitude: (max - min) / 2 of the LE radial displacement over every step of the kept window
(same as the HBM side); max |r| is stored too.
"""
from __future__ import annotations

import concurrent.futures
import math
import os
import time
from collections.abc import Callable
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field

import numpy as np

from hbm.options import CasingOptions, ContactOptions, TimeIntegrationOptions
from hbm.processes import (gathered, limit_blas_threads, mpi_world, process_context, run_flagged, running,
                           set_start_flags, start_flags, worker_died)
from hbm.ti.march import (Marcher, ModalSystem, Recording, check_time_step, load_kernel, rom_modal_system,
                          scheme_system)
from hbm.ti.settle import SUBSECTIONS, settle_test

#: Steps between two settle tests (rounded up to whole revolutions): every revolution at
#: dt = 1e-7 up to 2000 rad/s. One test (classifier, differences on the window over every
#: lag, the chunk's call into the kernel) costs about 0.5 ms, 4e3 to 5e3 steps of today's
#: kernel: 10 % of a march that never settles at 2000 rad/s (0.78 s against 0.70 s with
#: --no-early-stop, benchmarks/bench_ti.py), less at lower speeds (more steps a revolution).
_SETTLE_CHECK_STEPS = 30_000


#: Revolutions of boundary state kept per speed (SweepResult.boundary): two hold the orbits of
#: period 2 pi / Omega and those of twice that period (omega = Omega / 2, the period-doubled
#: branches), which seed an isola search in the basis of Omega / 2 ([hbm] subharmonic = 2).
BOUNDARY_REVOLUTIONS = 2


@dataclass(frozen=True)
class SpeedResponse:
    """Steady response at one rotation speed (fields as the rows of SweepResult)."""

    omega: float = field(metadata={"unit": "rad/s"})
    amplitude: float = field(metadata={"unit": "m"})
    max_abs: float = field(metadata={"unit": "m"})
    period_class: int = field(metadata={"unit": "1"})
    period: int = field(metadata={"unit": "1"})
    order: float = field(metadata={"unit": "1"})
    mismatch: float = field(metadata={"unit": "1"})
    dt: float = field(metadata={"unit": "s"})
    times: np.ndarray = field(metadata={"unit": "s"})
    displacement: np.ndarray = field(metadata={"unit": "m"})
    normal_force: np.ndarray = field(metadata={"unit": "N"})
    sections: np.ndarray = field(metadata={"unit": "m"})
    contact_fraction: float = field(metadata={"unit": "1"})
    max_penetration: float = field(metadata={"unit": "m"})
    revolutions: int = field(metadata={"unit": "1"})
    transient_bound: float = field(metadata={"unit": "1"})
    cpu_time: float = field(metadata={"unit": "s"})
    boundary: np.ndarray | None = field(default=None, metadata={"unit": "m"})
    active_set_failures: int | None = field(default=0, metadata={"unit": "1"})
    explicit_direction_steps: int | None = field(default=0, metadata={"unit": "1"})


@dataclass(frozen=True)
class SweepResult:
    """Time-integration NFRC, one row per rotation speed (n_omega rows).

    omega: Omega, (n_omega,), rad/s.
    amplitude: (max - min) / 2 of the LE radial displacement over the kept window, (n_omega,), m.
    max_abs: max |r| of the LE over the kept window, (n_omega,), m.
    period_class: hbm.ti.periodicity.PeriodClass code (0: omega = n_l Omega (2 Omega), 1: omega
        = Omega, 2: subharmonic, 3: none / omega < Omega / max_order, 4: Omega < omega < n_l Omega),
        (n_omega,).
    period: period in casing periods p (0 when none), (n_omega,). order: nu = Omega / omega
        = p / n_l (nan when none), (n_omega,), -. mismatch: section mismatch of the accepted
        period relative to the range (the best one when none), (n_omega,), -.
    dt: time step actually used (<= the requested one), (n_omega,), s.
    times: sample times of the kept window, (n_omega, n_samples), s.
    displacement: radial displacement of the LE and TE, (n_omega, n_samples, 2), m.
    normal_force: normal contact force lam >= 0 of the LE and TE, block means over the
        sample interval (keeps the impulse of impacts), (n_omega, n_samples, 2), N.
    sections: radial displacement of every contact node at each casing period of the kept
        window (Poincare sections), (n_omega, n_keep n_l + 1, n_b), m.
    contact_fraction: share of the steps with at least one node in contact, (n_omega,), -.
    max_penetration: largest r_j - d_j after the contact correction, (n_omega,), m (round-off
        where a node touched; else the closest approach, < 0, or -inf: see March).
    revolutions: revolutions marched, n_revolutions unless the march settled earlier, (n_omega,).
    transient_bound: bound on the transient left in the window, relative to each node's range
        (hbm.ti.settle), (n_omega,), -; <= settle_rtol where the march stopped early, inf where
        no period was found.
    cpu_time: CPU time of each point, of the process that marched it (one thread: BLAS on one
        thread in the workers), (n_omega,), s; numba's compilation of the step loop (the first
        point of a process, where the cache is cold) is not counted (hbm.ti.march.load_kernel).
    boundary: every boundary dof (r, theta, z of each contact node, node-major, the HBM's
        order) over the last BOUNDARY_REVOLUTIONS revolutions of the window, samples_per_revolution
        samples a revolution from a whole revolution (Omega t = 0 mod 2 pi),
        (n_omega, BOUNDARY_REVOLUTIONS samples_per_revolution, 3 n_b), m: the state an HBM
        solution can be started from (hbm.isolas); None in files written before it was kept
        (and one revolution only in files written before two were).
    active_set_failures: steps whose contact solve hit its iteration cap and kept a clipped
        iterate (hbm.ti.march.March), (n_omega,): 0 where the contact was solved exactly at
        every step, -1 where unknown (a speed resumed from a file written before it was
        counted); None in files written before it.
    explicit_direction_steps: contact steps whose friction direction did not settle (a sliding
        reversal within the step, or hbm.ti.kernel.DIRECTION_PASSES passes) and which took the
        prediction's direction instead (March.explicit_direction_steps), (n_omega,): their
        friction carries the O(dt) error the settled direction removes; -1 where unknown, None
        in files written before it.
    """

    omega: np.ndarray = field(metadata={"unit": "rad/s"})
    amplitude: np.ndarray = field(metadata={"unit": "m"})
    max_abs: np.ndarray = field(metadata={"unit": "m"})
    period_class: np.ndarray = field(metadata={"unit": "1"})
    period: np.ndarray = field(metadata={"unit": "1"})
    order: np.ndarray = field(metadata={"unit": "1"})
    mismatch: np.ndarray = field(metadata={"unit": "1"})
    dt: np.ndarray = field(metadata={"unit": "s"})
    times: np.ndarray = field(metadata={"unit": "s"})
    displacement: np.ndarray = field(metadata={"unit": "m"})
    normal_force: np.ndarray = field(metadata={"unit": "N"})
    sections: np.ndarray = field(metadata={"unit": "m"})
    contact_fraction: np.ndarray = field(metadata={"unit": "1"})
    max_penetration: np.ndarray = field(metadata={"unit": "m"})
    revolutions: np.ndarray = field(metadata={"unit": "1"})
    transient_bound: np.ndarray = field(metadata={"unit": "1"})
    cpu_time: np.ndarray = field(metadata={"unit": "s"})
    boundary: np.ndarray | None = field(default=None, metadata={"unit": "m"})
    active_set_failures: np.ndarray | None = field(default=None, metadata={"unit": "1"})
    explicit_direction_steps: np.ndarray | None = field(default=None, metadata={"unit": "1"})


def steps_per_revolution(omega: float, dt: float, multiple: int) -> int:
    """Smallest multiple N of `multiple` with 2 pi / (omega N) <= dt. omega: rad/s, dt: s."""
    per_rev = 2.0 * math.pi / (omega * dt)
    return int(multiple * math.ceil(per_rev / multiple - 1e-9))


def simulate(system: ModalSystem, casing: CasingOptions, mu: float, omega: float,
             options: TimeIntegrationOptions) -> SpeedResponse:
    """One point of the sweep: from rest at rotation speed omega (rad/s) until settled or
    n_revolutions. system: the full ModalSystem (or the scheme's, see scheme_system)."""
    t_start = time.process_time()  # CPU, not wall: a speed marched beside the NFRCs' processes
    # shares the cores with them, and its wall time would say how busy the machine was
    system = scheme_system(system, options.scheme, options.massless_cutoff)
    n_l, spr, n_keep = casing.n_lobes, options.samples_per_revolution, options.n_keep
    if n_keep * n_l < 2:  # checked before the march, not after its first n_keep + 1 revolutions
        raise ValueError(f"n_keep = {n_keep} revolutions of a casing with {n_l} lobe(s) give {n_keep * n_l + 1} "
                         "Poincare sections; the periodicity class needs at least 3")
    n_rev = steps_per_revolution(omega, options.dt, math.lcm(n_l * SUBSECTIONS, spr))
    dt = 2.0 * math.pi / (omega * n_rev)
    loading = time.process_time()
    load_kernel(system, casing, mu, omega, dt, exponential=options.scheme == "exponential")
    t_start += time.process_time() - loading  # the process's compile, not this speed's march
    nb = system.n_boundary
    n_max = options.n_revolutions
    sub_stride = n_rev // (n_l * SUBSECTIONS)
    # every revolution from the first is recorded: where the window ends is known only at the end.
    # All 3 n_b boundary dof are recorded (the last revolutions seed the isola search; LE and
    # TE radial are dof 0 and 3 (n_b - 1)); at a sample per 1/spr revolution this costs
    # nothing next to the steps.
    # Recording positions count from step n_rev: sample i at n_rev + i stride, extreme block b
    # covers steps (b + 1) n_rev .. (b + 2) n_rev - 1 (revolution b + 1 and its end point).
    rec = Recording(start=n_rev, stride=n_rev // spr, n_samples=(n_max - 1) * spr + 1,
                    dofs=np.arange(3 * nb), force_nodes=np.arange(nb),
                    section_stride=sub_stride, extreme_stride=n_rev)
    zero = np.zeros(system.n_dof)
    marcher = Marcher(system, casing, mu, omega, zero, zero, dt, n_max * n_rev, rec,
                      exponential=options.scheme == "exponential")
    decay_time = system.slowest_decay_time()
    every = max(1, math.ceil(_SETTLE_CHECK_STEPS / n_rev))
    revs = 0
    verdict = None
    while revs < n_max:
        step = min(every, n_max - revs) if revs >= n_keep + 1 else n_keep + 1 - revs
        marcher.advance(step * n_rev)
        revs += step
        if revs >= n_max or (options.stop_when_settled and revs > n_keep + 1):
            verdict = _settle(marcher, revs, n_l, n_keep, omega, decay_time, options)
            if verdict.settled:
                break
    return _response(marcher, verdict, revs, n_rev, spr, n_l, n_keep, omega, t_start)


def _settle(marcher: Marcher, revs: int, n_l: int, n_keep: int, omega: float, decay_time: float,
            options: TimeIntegrationOptions):
    """The settle test on the window of the last n_keep of `revs` revolutions."""
    spr = options.samples_per_revolution
    n_sub = (revs - 1) * n_l * SUBSECTIONS + 1  # sub-sections recorded up to the end of revolution revs
    n_f = (revs - 1) * spr  # force samples whose block is complete (the next one straddles the end)
    return settle_test(marcher.out_sec[:n_sub], marcher.out_ext[:revs], marcher.out_f[:n_f, :, 0], spr, n_l,
                       n_keep, omega, decay_time, options.periodicity_rtol, options.max_order, options.settle_rtol)


def _response(marcher: Marcher, verdict, revs: int, n_rev: int, spr: int, n_l: int, n_keep: int, omega: float,
              t_start: float) -> SpeedResponse:
    """SpeedResponse of the window of the last n_keep of `revs` revolutions."""
    m = marcher.result()
    w0 = revs - n_keep - 1  # extreme block and sample revolution where the window starts
    ext = m.extremes[w0:revs]  # n_keep + 1 blocks: the window's steps (w0 + 1) n_rev .. revs n_rev
    rmax, rmin = ext[:, 0].max(axis=0), ext[:, 1].min(axis=0)
    per = verdict.periodicity
    samples = slice(w0 * spr, (w0 + n_keep) * spr)
    last = slice((w0 + n_keep - min(BOUNDARY_REVOLUTIONS, n_keep)) * spr, (w0 + n_keep) * spr)
    nb = m.displacement.shape[1] // 3
    n_sub = (revs - 1) * n_l * SUBSECTIONS + 1
    sections = m.sections[n_sub - 1 - n_keep * n_l * SUBSECTIONS:n_sub:SUBSECTIONS]
    return SpeedResponse(
        omega=float(omega), amplitude=0.5 * float(rmax[0] - rmin[0]), max_abs=float(max(rmax[0], -rmin[0])),
        period_class=int(per.code), period=per.period, order=per.order, mismatch=per.mismatch, dt=m.dt,
        times=m.times[samples], displacement=m.displacement[samples][:, [0, 3 * (nb - 1)]],
        normal_force=m.normal_force[samples][:, [0, -1]],
        sections=sections, contact_fraction=m.contact_steps / (revs * n_rev), max_penetration=m.max_penetration,
        revolutions=int(revs), transient_bound=float(verdict.bound), cpu_time=time.process_time() - t_start,
        boundary=np.array(m.displacement[last]), active_set_failures=int(m.active_set_failures),
        explicit_direction_steps=int(m.explicit_direction_steps))


def sweep(rom, casing: CasingOptions, contact: ContactOptions, ti_options: TimeIntegrationOptions,
          omegas: np.ndarray | None = None, workers: int | None = None,
          on_point: Callable[[int, int], None] | None = None, done: dict | None = None,
          on_speed: Callable[[int, "SpeedResponse"], None] | None = None) -> SweepResult:
    """Time-integration sweep over rotation speeds.

    rom: rom.model.RomModel (or a ModalSystem, full or already massless). omegas: rotation
    speeds, (n_omega,), rad/s; default: the grid of ti_options. workers: local processes
    (default: all usable cores; ignored under MPI, where each rank takes every size-th point
    and all ranks get the result). on_point(done, total): called in this process after each
    point (under MPI: with this rank's own counts), e.g. to show progress. done: {index in
    omegas: SpeedResponse} of speeds already marched (an interrupted sweep's), not marched
    again; on_speed(index, SpeedResponse): called in this process as each other speed ends
    (under MPI, on each rank for its own speeds), e.g. to keep it on disk.
    Raises ValueError when ti_options.dt exceeds the scheme's stability limit. Under MPI a
    failure on one rank (a speed, on_speed) is raised there and as RankFailed on the others.
    """
    system, omegas = _prepared(rom, contact, ti_options, omegas)
    mu = contact.mu
    comm = mpi_world()
    progress = on_point or (lambda done, total: None)
    keep = on_speed or (lambda i, response: None)
    points = dict(done or {})
    if comm is not None:
        mine = [i for i in range(comm.rank, len(omegas), comm.size) if i not in points]
        local, error = [], None
        try:
            for k, i in enumerate(mine):
                local.append((i, simulate(system, casing, mu, omegas[i], ti_options)))
                keep(*local[-1])
                progress(k + 1, len(mine))
        except Exception as exc:  # noqa: BLE001 - every rank must reach the allgather, or the others wait forever
            error = exc
        parts = gathered(comm, local, error, "the time-integration sweep")
        points.update(p for part in parts for p in part)
        return _stack([points[i] for i in range(len(omegas))])
    n_workers = workers or len(os.sched_getaffinity(0))
    if n_workers <= 1 or len(omegas) - len(points) <= 1:
        for i in np.argsort(omegas):  # slowest points (low Omega, most steps) first
            if i not in points:
                points[i] = simulate(system, casing, mu, omegas[i], ti_options)
                keep(int(i), points[i])
                progress(len(points), len(omegas))
        return _stack([points[i] for i in range(len(omegas))])
    run = SweepRun(system, casing, contact, ti_options, omegas, n_workers, n_workers, on_point=progress,
                   done=points, on_speed=on_speed)
    try:
        return run.result()
    finally:
        run.cancel()


def _prepared(rom, contact: ContactOptions, ti_options: TimeIntegrationOptions, omegas):
    """(the scheme's ModalSystem, the speeds (n_omega,), rad/s), both checked."""
    system = rom if isinstance(rom, ModalSystem) else rom_modal_system(rom)
    system = scheme_system(system, ti_options.scheme, ti_options.massless_cutoff)
    check_time_step(system, ti_options.dt, contact.mu, ti_options.scheme == "exponential")
    if omegas is None:
        omegas = ti_options.omegas
    omegas = np.atleast_1d(np.asarray(omegas, dtype=float))
    if omegas.ndim != 1 or omegas.size == 0:
        raise ValueError(f"the sweep needs a list of rotation speeds, got {omegas.size} speed(s) of shape "
                         f"{omegas.shape}")
    bad = omegas[~(np.isfinite(omegas) & (omegas > 0))]
    if len(bad):
        raise ValueError(f"rotation speeds must be finite and > 0 rad/s, got {', '.join(f'{w:g}' for w in bad)}")
    return system, omegas


def _sweep_worker(started) -> None:
    """Initializer of a SweepRun's workers: BLAS on one thread, and the start flags at hand
    (hbm.processes.run_flagged: a dead worker's speeds are named)."""
    set_start_flags(started)
    limit_blas_threads()


class SweepRun:
    """A sweep on a local process pool that may start before every core is free for it.

    The pool has one worker per core (`workers`), all started here (fork: from the calling
    thread, before any other work starts processes); at most `cores` speeds are in flight
    (all the rest are queued once every worker has its core), and lend(n) raises that as
    other work on the machine ends (pipelines.runner starts the
    sweep beside the NFRCs, whose processes hand it their cores as they end). The speeds
    go slowest first (low Omega, most steps), as in sweep(). on_point(done, total) is
    called after each point, from the pool's thread; so is on_speed(index, SpeedResponse),
    before it (what it raises fails the sweep, as a failing speed does). done: {index:
    SpeedResponse} of speeds not to march again (counted as done). Not for MPI runs.

    rom: as for sweep(). omegas: (n_omega,), rad/s (default: the grid of ti_options).
    Raises ValueError (dt past the scheme's stability limit, a speed <= 0) when built.
    """

    def __init__(self, rom, casing: CasingOptions, contact: ContactOptions, ti_options: TimeIntegrationOptions,
                 omegas: np.ndarray | None = None, workers: int | None = None, cores: int | None = None,
                 on_point: Callable[[int, int], None] | None = None, done: dict | None = None,
                 on_speed: Callable[[int, "SpeedResponse"], None] | None = None):
        import threading

        self._system, self.omegas = _prepared(rom, contact, ti_options, omegas)
        self._args = (casing, contact.mu, ti_options)
        self._points: dict = dict(done or {})
        self._todo = [int(i) for i in np.argsort(self.omegas) if i not in self._points]
        workers = max(1, min(workers or len(os.sched_getaffinity(0)), len(self._todo)))
        self._workers = workers
        self._cores = workers if cores is None else max(0, min(cores, workers))
        self._error: BaseException | None = None
        self._in_flight = 0
        self._lock = threading.RLock()  # a done callback may run at once, inside _fill
        self._finished = threading.Event()
        self.on_point = on_point or (lambda done, total: None)
        self.on_speed = on_speed or (lambda i, response: None)
        context = process_context()
        self._started = start_flags(context, len(self.omegas))
        self._pool = concurrent.futures.ProcessPoolExecutor(workers, mp_context=context, initializer=_sweep_worker,
                                                            initargs=(self._started,))
        # with fork the pool starts all its workers at its first task: here, from this thread
        self._pool.submit(int).result()
        self._fill()

    @property
    def done(self) -> int:
        """Speeds finished so far."""
        return len(self._points)

    def lend(self, n: int = 1) -> None:
        """n more cores for the sweep (at most one per worker)."""
        with self._lock:
            self._cores = min(self._cores + n, self._workers)
            self._fill()

    def _fill(self) -> None:
        with self._lock:
            # once every worker has its core, everything goes to the pool's own queue (as a
            # plain sweep does): a worker then starts its next speed without waiting for
            # this callback's round trip
            while self._todo and self._error is None and (self._in_flight < self._cores
                                                          or self._cores >= self._workers):
                i = self._todo.pop(0)
                self._in_flight += 1
                self._pool.submit(run_flagged, i, simulate, self._system, *self._args[:2], self.omegas[i],
                                  self._args[2]) \
                    .add_done_callback(lambda f, i=i: self._done(i, f))
            if self._in_flight == 0 and (self._error is not None or not self._todo):
                self._finished.set()

    def _done(self, i: int, future) -> None:
        with self._lock:
            self._in_flight -= 1
            if not future.cancelled():  # cancelled: the sweep is being ended (cancel())
                error = future.exception()
                if isinstance(error, BrokenProcessPool):
                    marched = [f"{self.omegas[j]:g}" for j in running(self._started)]
                    error = worker_died("the time-integration sweep",
                                        f"speeds being marched: {', '.join(marched)} rad/s" if marched else "")
                if error is None:
                    try:  # the pool would only log what a callback raises
                        self.on_speed(i, future.result())
                    except Exception as exc:  # noqa: BLE001 - the sweep's failure, raised by result()
                        error = exc
                if error is not None:
                    self._error = self._error or error
                else:
                    self._points[i] = future.result()
                    self.on_point(len(self._points), len(self.omegas))
            self._fill()

    def result(self) -> SweepResult:
        """Waits for every speed (lending every worker its core first: nothing else runs
        now) and returns the sweep; raises the first failure of a speed."""
        self.lend(self._workers)
        while not self._finished.wait(0.2):  # a timed wait: Ctrl-C is answered at once
            pass
        self._pool.shutdown()
        if self._error is not None:
            raise self._error
        return _stack([self._points[i] for i in range(len(self.omegas))])

    def cancel(self) -> None:
        """Ends the sweep now: no further speed starts and the workers are stopped."""
        with self._lock:
            self._todo.clear()
        for p in list((getattr(self._pool, "_processes", None) or {}).values()):
            if p.is_alive():
                p.terminate()
        self._pool.shutdown(wait=True, cancel_futures=True)


#: Per-speed step counts that a speed resumed from an older partial file may lack (-1: unknown).
_COUNTS = ("active_set_failures", "explicit_direction_steps")


def _stack(rows: list[SpeedResponse]) -> SweepResult:
    names = [f.name for f in SweepResult.__dataclass_fields__.values() if f.name not in _COUNTS]
    counts = {k: np.array([-1 if getattr(r, k) is None else getattr(r, k) for r in rows], dtype=int) for k in _COUNTS}
    return SweepResult(**{k: np.array([getattr(r, k) for r in rows]) for k in names}, **counts)
