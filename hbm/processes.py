"""How independent tasks are spread: the start method of the worker processes (sweep, isola
search, hbm stage) and the MPI world when the run is under a launcher."""
from __future__ import annotations

import multiprocessing
import os
import sys


def process_context():
    """multiprocessing context: "fork" (cheapest: workers inherit the compiled kernels and
    the built residuals) unless MPI is initialised in this process (dolfinx does it in the
    fem stage; mpi4py's state does not survive a fork), then "spawn"."""
    return multiprocessing.get_context("spawn" if "mpi4py.MPI" in sys.modules else "fork")


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
