"""Running the stages under an MPI launcher (`mpirun -n N bladerub run ...`).

One rank (0) does what is serial (meshing, the ROM, HBM, writing artifacts, figures);
all ranks take part in what is distributed (the FEM stage, the time-integration sweep).
The helpers here keep the ranks in step and make a failure on one rank end the run on
all of them with its message, instead of leaving the others waiting forever.
"""
from __future__ import annotations

import time

from hbm.processes import RankFailed  # noqa: F401 (one class for hbm's collective steps and these)
from hbm.processes import mpi_world as world  # noqa: F401 (the stages' name for it)


def is_root(comm) -> bool:
    return comm is None or comm.rank == 0


def _idle_barrier(comm, poll_s: float = 0.02) -> None:
    # A blocking MPI wait spins a core at 100 %; ranks waiting for rank 0's serial work
    # would take that core from rank 0's BLAS threads. Poll a non-blocking barrier instead.
    req = comm.Ibarrier()
    while not req.Test():
        time.sleep(poll_s)


def _describe(exc: BaseException) -> str:
    return f"{type(exc).__name__}: {exc}"


def on_root(comm, fn):
    """fn() on rank 0 only (the others wait, idle); its return value on every rank.

    If fn raises on rank 0, rank 0 re-raises it and the other ranks raise RankFailed.
    comm None: just fn().
    """
    if comm is None:
        return fn()
    value, error = None, None
    if comm.rank == 0:
        try:
            value = fn()
        except BaseException as exc:  # noqa: BLE001 - relayed, then re-raised below
            error = exc
    _idle_barrier(comm)
    ok, payload = comm.bcast((error is None, value if error is None else _describe(error)), root=0)
    if error is not None:
        raise error
    if not ok:
        raise RankFailed(f"rank 0 failed: {payload}")
    return payload


def on_all(comm, fn):
    """fn() on every rank (a collective step); if it raises on any rank, that rank
    re-raises its exception and the others raise RankFailed naming it. Returns fn()'s
    value of this rank. comm None: just fn().

    (A rank that fails inside a collective call of fn leaves the others blocked there:
    MPI offers no way out but the launcher; fn's own checks should come before its
    collective calls, as the FEM stage's input checks do.)
    """
    if comm is None:
        return fn()
    value, error = None, None
    try:
        value = fn()
    except BaseException as exc:  # noqa: BLE001 - relayed, then re-raised below
        error = exc
    failures = [(r, msg) for r, msg in enumerate(comm.allgather(None if error is None else _describe(error)))
                if msg is not None]
    if error is not None:
        raise error
    if failures:
        r, msg = failures[0]
        raise RankFailed(f"rank {r} failed: {msg}")
    return value
