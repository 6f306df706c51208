"""How independent tasks are spread: the start method of the worker processes (sweep, isola
search, hbm stage) and the MPI world when the run is under a launcher."""
from __future__ import annotations

import ctypes
import multiprocessing
import os
import sys
import time
from collections.abc import Callable
from contextlib import contextmanager


def process_context():
    """multiprocessing context: "fork" (cheapest: workers inherit the compiled kernels and
    the built residuals) unless MPI is initialised in this process (dolfinx does it in the
    fem stage; mpi4py's state does not survive a fork), then "spawn"."""
    return multiprocessing.get_context("spawn" if "mpi4py.MPI" in sys.modules else "fork")


class WorkerDied(RuntimeError):
    """A worker process of a pool ended without an answer: killed (the kernel's OOM killer,
    a user) or crashed. What it was computing is lost; what the pool finished before is not."""


class RankFailed(RuntimeError):
    """Raised on the MPI ranks that did not fail when another rank did (the message says
    which rank and why); the failing rank raises its own exception."""


def _describe(exc: BaseException) -> str:
    return f"{type(exc).__name__}: {exc}"


def _failed(r: int, what: str, why: str) -> RankFailed:
    return RankFailed(f"rank {r} failed{f' in {what}' if what else ''}: {why}")


def idle_barrier(comm, poll_s: float = 0.02) -> None:
    """An MPI barrier that sleeps while it waits: a blocking MPI wait spins a core at 100 %,
    which ranks waiting for rank 0's serial work would take from rank 0's BLAS threads."""
    req = comm.Ibarrier()
    while not req.Test():
        time.sleep(poll_s)


def gathered(comm, value, error: BaseException | None, what: str = "") -> list:
    """comm.allgather(value) on an MPI communicator where this rank's share of the work may
    have failed (error; None when it did not): every rank reaches the gathering, the failing
    rank re-raises its error and the others raise RankFailed naming it and `what` (e.g. "the
    time-integration sweep"), where a rank that raised before the gathering would leave the
    others waiting in it forever. Returns every rank's value, in rank order."""
    parts = comm.allgather((value, None if error is None else _describe(error)))
    if error is not None:
        raise error
    for r, (_, why) in enumerate(parts):
        if why is not None:
            raise _failed(r, what, why)
    return [v for v, _ in parts]


def on_root(comm, fn, what: str = ""):
    """fn() on rank 0 only (the others wait, idle); its return value on every rank. If fn
    raises on rank 0, rank 0 re-raises it and the other ranks raise RankFailed (naming
    `what`). comm None: just fn()."""
    if comm is None:
        return fn()
    value, error = None, None
    if comm.rank == 0:
        try:
            value = fn()
        except BaseException as exc:  # noqa: BLE001 - relayed, then re-raised below
            error = exc
    idle_barrier(comm)
    ok, payload = comm.bcast((error is None, value if error is None else _describe(error)), root=0)
    if error is not None:
        raise error
    if not ok:
        raise _failed(0, what, payload)
    return payload


def on_all(comm, fn):
    """fn() on every rank (a collective step); if it raises on any rank, that rank
    re-raises its exception and the others raise RankFailed naming it. Returns fn()'s
    value of this rank. comm None: just fn().

    (A rank that fails inside a collective call of fn leaves the others blocked there:
    MPI offers no way out but the launcher; fn's own checks should come before its
    collective calls, as the FEM stage's input checks do, and a loop of work before a
    gathering passes its error to it: see gathered.)
    """
    if comm is None:
        return fn()
    value, error = None, None
    try:
        value = fn()
    except BaseException as exc:  # noqa: BLE001 - relayed, then re-raised by gathered
        error = exc
    gathered(comm, None, error)
    return value


def worker_died(what: str, tasks: str = "") -> WorkerDied:
    """The WorkerDied of a pool of `what` (e.g. "the isola search"), for its BrokenProcessPool:
    Python's own text names no task and reads as a bug (a traceback in the CLI). tasks: what
    the pool's workers were computing when it broke, where the pool knows (e.g. "speeds being
    marched: 650 rad/s")."""
    return WorkerDied(f"a worker process of {what} ended without an answer (killed, perhaps for lack of memory)"
                      + (f"; {tasks}" if tasks else ""))


@contextmanager
def reported_deaths(what: str, tasks: Callable[[], str] | None = None):
    """Within it, a pool's BrokenProcessPool is raised as worker_died(what, tasks()); tasks:
    a callable that says what the pool's workers were computing when it broke (None: the
    message names only the pool), asked only then."""
    from concurrent.futures.process import BrokenProcessPool

    try:
        yield
    except BrokenProcessPool as exc:
        raise worker_died(what, tasks() if tasks is not None else "") from exc


#: In a pool's worker process: (its pid, the pool's start flags) (set_start_flags), or None.
_STARTED = None


def start_flags(context, n: int):
    """The start flags of a pool's n tasks: one byte per task in shared memory, all 0.

    A pool's owner knows which answers reached it, not which tasks were running when a
    worker died (the OOM killer): the workers get the flags from their initializer
    (set_start_flags) and each task runs through run_flagged, which sets its flag to 1 as
    it starts and to 2 as it returns or raises (an answer that a broken pool lost was not
    being computed). running(flags): the tasks being computed. context: the pool's
    multiprocessing context."""
    return context.RawArray("b", n)


def set_start_flags(flags) -> None:
    """Pool initializer (or part of one): this worker's tasks set their flags in `flags`
    (this process's only: a pool started from a task forks workers that inherit them, whose
    tasks are not this pool's)."""
    global _STARTED
    _STARTED = (os.getpid(), flags)


def run_flagged(i: int, fn, *args):
    """fn(*args) as task i of a pool, its flag set around it (start_flags). fn travels with
    the task: a spawned worker imports its module afresh, where a test's replacement of a
    module function would be lost."""
    if _STARTED is None or _STARTED[0] != os.getpid():  # not a worker of a flagged pool (or one it started)
        return fn(*args)
    flags = _STARTED[1]
    flags[i] = 1
    try:
        return fn(*args)
    finally:
        flags[i] = 2


def running(flags) -> list[int]:
    """Indices of the tasks started and not returned (start_flags)."""
    return [i for i in range(len(flags)) if flags[i] == 1]


_LIMITS: list = []  # keeps each worker's BLAS limit alive for its lifetime


def limit_blas_threads() -> None:
    """Worker-process initializer: BLAS on one thread. The pools run one process per core;
    a threaded BLAS call in one worker would otherwise wake threads that compete with the
    other workers for the same cores (and spin after each call)."""
    from threadpoolctl import threadpool_limits

    _LIMITS.append(threadpool_limits(limits=1, user_api="blas"))


#: glibc's mallopt parameters (malloc.h)
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3
#: The largest M_MMAP_THRESHOLD glibc accepts on 64-bit (half its 64 MiB heap size)
_MMAP_THRESHOLD_MAX = 32 * 2**20


def keep_freed_memory() -> None:
    """Worker-process initializer: glibc's allocator keeps what the worker frees for its next
    allocations. By default a block over a threshold that grows from 128 KiB is mapped afresh
    at each allocation and unmapped when freed, and the heap's free top is given back past
    twice that threshold: a worker's Newton steps allocate and free the same 1-30 MB arrays
    many times a second, and every page they touch again is a page fault and zeroed by the
    kernel (in the isola search's workers ~9 % of their CPU time was the kernel's). With the
    threshold at its maximum and no trimming, the worker's resident set stays at its peak,
    which it reaches anyway: a pool's workers end with their task list. Does nothing
    elsewhere than glibc."""
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):  # not glibc
        return
    mallopt(_M_MMAP_THRESHOLD, _MMAP_THRESHOLD_MAX)
    mallopt(_M_TRIM_THRESHOLD, 2**31 - 1)


#: The launchers' environment variables: a process that has one is a rank of an MPI job.
_LAUNCHED = ("OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK", "MPI_LOCALNRANKS")


def isolate_mpi_singleton() -> None:
    """Outside an MPI launcher, MPI starts (when dolfinx initialises it) as a singleton, and
    Open MPI 4 starts a helper daemon (orted) for every singleton process. Several such
    processes starting and stopping at once (test runs beside their test processes, runs
    interrupted by Ctrl-C) now and then crashed: PETSc's SEGV handler and exit 59, "ORTE_ERROR_LOG:
    Data unpack would read past end of buffer", or a test worker lost (about one run in four
    of tests/pipelines/test_interrupt.py on two workers; none in 12 with this). An isolated
    singleton (Open MPI's ess_singleton_isolated) starts no daemon; bladerub never spawns MPI
    processes, the one thing it would need one for. Set in the environment before any MPI
    initialisation (hbm/__init__), unless the user set it or a launcher started us; other MPI
    implementations ignore it."""
    if not any(k in os.environ for k in _LAUNCHED):
        os.environ.setdefault("OMPI_MCA_ess_singleton_isolated", "1")


def mpi_world():
    """mpi4py COMM_WORLD when this process runs under an MPI launcher with more than one
    rank, else None (mpirun -n 1 and plain runs take the serial path).

    mpi4py is imported only when a launcher's environment is seen (or when it already is),
    so that plain runs never initialise MPI.
    """
    launched = any(k in os.environ for k in _LAUNCHED)
    if not launched and "mpi4py.MPI" not in sys.modules:
        return None
    try:
        from mpi4py import MPI
    except ImportError:
        return None
    comm = MPI.COMM_WORLD
    return comm if comm.Get_size() > 1 else None
