"""How independent tasks are spread: the start method of the worker processes (sweep, isola
search, hbm stage) and the MPI world when the run is under a launcher."""
from __future__ import annotations

import multiprocessing
import os
import sys
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


def gathered(comm, value, error: BaseException | None, what: str) -> list:
    """comm.allgather(value) on an MPI communicator where this rank's share of the work may
    have failed (error; None when it did not): every rank reaches the gathering, the failing
    rank re-raises its error and the others raise RankFailed naming it and `what` (e.g. "the
    time-integration sweep"), where a rank that raised before the gathering would leave the
    others waiting in it forever. Returns every rank's value, in rank order."""
    parts = comm.allgather((value, None if error is None else f"{type(error).__name__}: {error}"))
    if error is not None:
        raise error
    for r, (_, why) in enumerate(parts):
        if why is not None:
            raise RankFailed(f"rank {r} failed in {what}: {why}")
    return [v for v, _ in parts]


def worker_died(what: str) -> WorkerDied:
    """The WorkerDied of a pool of `what` (e.g. "the isola search"), for its BrokenProcessPool:
    Python's own text names no task and reads as a bug (a traceback in the CLI)."""
    return WorkerDied(f"a worker process of {what} ended without an answer (killed, perhaps for lack of memory)")


@contextmanager
def reported_deaths(what: str):
    """Within it, a pool's BrokenProcessPool is raised as worker_died(what)."""
    from concurrent.futures.process import BrokenProcessPool

    try:
        yield
    except BrokenProcessPool as exc:
        raise worker_died(what) from exc


_LIMITS: list = []  # keeps each worker's BLAS limit alive for its lifetime


def limit_blas_threads() -> None:
    """Worker-process initializer: BLAS on one thread. The pools run one process per core;
    a threaded BLAS call in one worker would otherwise wake threads that compete with the
    other workers for the same cores (and spin after each call)."""
    from threadpoolctl import threadpool_limits

    _LIMITS.append(threadpool_limits(limits=1, user_api="blas"))


def mpi_world():
    """mpi4py COMM_WORLD when this process runs under an MPI launcher with more than one
    rank, else None (mpirun -n 1 and plain runs take the serial path).

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
