"""Time-integration frequency sweep (section 3.1 and Fig. 5 of the reference paper).

For each rotation speed Omega: n_revolutions revolutions from null initial conditions, the
last n_keep kept for the leading-edge (LE) amplitude, the periodicity class and the
downsampled LE/TE signals. Points run in parallel: over MPI ranks when launched under
mpirun (communicator size > 1), otherwise over a local process pool (all cores by default).

The time step is shrunk from dt to dt_eff = T / N <= dt, N the smallest multiple of
lcm(n_lobes, samples_per_revolution) with N >= T / dt: revolutions, casing periods and
output samples then fall on steps, so no signal needs interpolation, and dt_eff stays stable.

Amplitude: (max - min) / 2 of the LE radial displacement over the kept window (same as the
HBM side); max |r| is stored too.
"""
from __future__ import annotations

import math
import os
import sys
import time
from dataclasses import dataclass, field

import numpy as np

from hbm.options import CasingOptions, ContactOptions, TimeIntegrationOptions
from hbm.ti.periodicity import classify_period
from hbm.ti.march import ModalSystem, Recording, check_time_step, march, rom_modal_system


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
    cpu_time: float = field(metadata={"unit": "s"})


@dataclass(frozen=True)
class SweepResult:
    """Time-integration NFRC, one row per rotation speed (n_omega rows).

    omega: Omega, (n_omega,), rad/s.
    amplitude: (max - min) / 2 of the LE radial displacement over the kept window, (n_omega,), m.
    max_abs: max |r| of the LE over the kept window, (n_omega,), m.
    period_class: hbm.ti.periodicity code (0: omega = n_l Omega (2 Omega), 1: omega = Omega,
        2: subharmonic, 3: none / omega < Omega / max_order), (n_omega,).
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
    max_penetration: largest r_j - d_j after the contact correction, (n_omega,), m (round-off).
    cpu_time: wall time of each point in its worker, (n_omega,), s.
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
    cpu_time: np.ndarray = field(metadata={"unit": "s"})


def steps_per_revolution(omega: float, dt: float, multiple: int) -> int:
    """Smallest multiple N of `multiple` with 2 pi / (omega N) <= dt. omega: rad/s, dt: s."""
    per_rev = 2.0 * math.pi / (omega * dt)
    return int(multiple * math.ceil(per_rev / multiple - 1e-9))


def simulate(system: ModalSystem, casing: CasingOptions, mu: float, omega: float,
             options: TimeIntegrationOptions) -> SpeedResponse:
    """One point of the sweep: n_revolutions from rest at rotation speed omega (rad/s)."""
    t_start = time.perf_counter()
    n_l, spr = casing.n_lobes, options.samples_per_revolution
    n_rev = steps_per_revolution(omega, options.dt, math.lcm(n_l, spr))
    dt = 2.0 * math.pi / (omega * n_rev)
    nb = system.n_boundary
    rec = Recording(start=(options.n_revolutions - options.n_keep) * n_rev or 1, stride=n_rev // spr,
                    n_samples=options.n_keep * spr, dofs=np.array([0, 3 * (nb - 1)]),
                    force_nodes=np.array([0, nb - 1]), section_stride=n_rev // n_l)
    zero = np.zeros(system.n_dof)
    m = march(system, casing, mu, omega, zero, zero, dt, options.n_revolutions * n_rev, rec)
    # mismatch relative to each node's range over every step of the window
    per = classify_period(m.sections, n_lobes=n_l, rtol=options.periodicity_rtol, max_order=options.max_order,
                          scale=m.radial_max - m.radial_min)
    return SpeedResponse(
        omega=float(omega), amplitude=0.5 * float(m.radial_max[0] - m.radial_min[0]),
        max_abs=float(max(m.radial_max[0], -m.radial_min[0])), period_class=per.code, period=per.period,
        order=per.order, mismatch=per.mismatch, dt=dt, times=m.times, displacement=m.displacement,
        normal_force=m.normal_force, sections=m.sections,
        contact_fraction=m.contact_steps / (options.n_revolutions * n_rev),
        max_penetration=m.max_penetration, cpu_time=time.perf_counter() - t_start)


def sweep(rom, casing: CasingOptions, contact: ContactOptions, ti_options: TimeIntegrationOptions,
          omegas: np.ndarray | None = None, workers: int | None = None) -> SweepResult:
    """Time-integration sweep over rotation speeds.

    rom: rom.model.RomModel (or a ModalSystem). omegas: rotation speeds, (n_omega,), rad/s;
    default: the grid of ti_options. workers: local processes (default: all usable cores;
    ignored under MPI, where each rank takes every size-th point and all ranks get the result).
    Raises ValueError when ti_options.dt exceeds the stability limit.
    """
    system = rom if isinstance(rom, ModalSystem) else rom_modal_system(rom)
    check_time_step(system, ti_options.dt)
    if omegas is None:
        omegas = np.linspace(ti_options.omega_min, ti_options.omega_max, ti_options.n_omega)
    omegas = np.atleast_1d(np.asarray(omegas, dtype=float))
    if not (omegas > 0).all():
        raise ValueError("rotation speeds must be > 0 rad/s")
    mu = contact.mu
    comm = _mpi_world()
    if comm is not None:
        mine = [(i, simulate(system, casing, mu, omegas[i], ti_options))
                for i in range(comm.rank, len(omegas), comm.size)]
        points = dict(p for part in comm.allgather(mine) for p in part)
    else:
        n_workers = workers or len(os.sched_getaffinity(0))
        order = np.argsort(omegas)  # slowest points (low Omega, most steps) first
        if n_workers <= 1 or len(omegas) == 1:
            points = {i: simulate(system, casing, mu, omegas[i], ti_options) for i in order}
        else:
            import concurrent.futures
            import multiprocessing

            # fork is cheapest (the compiled kernel comes along) but unsafe once MPI is initialised
            ctx = multiprocessing.get_context("spawn" if "mpi4py.MPI" in sys.modules else "fork")
            with concurrent.futures.ProcessPoolExecutor(min(n_workers, len(omegas)), mp_context=ctx) as pool:
                futures = {pool.submit(simulate, system, casing, mu, omegas[i], ti_options): i for i in order}
                points = {futures[f]: f.result() for f in concurrent.futures.as_completed(futures)}
    rows = [points[i] for i in range(len(omegas))]
    return _stack(rows)


def _stack(rows: list[SpeedResponse]) -> SweepResult:
    names = [f.name for f in SweepResult.__dataclass_fields__.values()]
    return SweepResult(**{k: np.array([getattr(r, k) for r in rows]) for k in names})


def _mpi_world():
    """COMM_WORLD when this process runs under an MPI launcher with more than one rank, else None.

    mpi4py is imported only when a launcher's environment is seen (or when it already is),
    so that plain runs never initialise MPI.
    """
    launched = any(k in os.environ for k in ("OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK", "MPI_LOCALNRANKS"))
    if not launched and "mpi4py.MPI" not in sys.modules:
        return None
    try:
        from mpi4py import MPI
    except ImportError:
        return None
    comm = MPI.COMM_WORLD
    return comm if comm.Get_size() > 1 else None
