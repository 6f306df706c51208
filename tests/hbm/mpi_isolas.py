"""Run under `mpirun -n 2` by test_isolas.test_mpi_search_equals_the_serial_one: the search of
test_isolas (modal seeds, the primary as known branch) with the seeds shared among the
ranks; rank 0 saves the result to argv[1]. With argv[2] = "fail", rank 1's first seed
correction raises (test_a_failing_rank_ends_the_mpi_search_on_every_rank): each rank prints
what it raised and exits 3."""
import sys

import numpy as np
from mpi4py import MPI

from hbm.continuation.arclength import continue_branch
from hbm.isolas.membership import KnownBranch
from hbm.isolas.search import search
from test_isolas import F, W_MIN, Oscillator, continuation, factory, modal_seeds, options

comm = MPI.COMM_WORLD
br = continue_branch(Oscillator(), np.array([F / (1 - W_MIN ** 2), 0.0]), W_MIN, continuation())
primary = KnownBranch.of(br.omega, br.x, "primary", br.converged)
if sys.argv[2:] == ["fail"] and comm.rank == 1:
    import hbm.isolas.search as isolas_search

    def broken(corrector, items):
        raise FloatingPointError("a seed's correction failed on rank 1 for the test")

    isolas_search._timed = broken
try:
    res = search(factory, modal_seeds(), [primary], options(), comm=comm)
except Exception as exc:  # noqa: BLE001 - what each rank raised, for the test
    print(f"rank {comm.rank} raised {type(exc).__name__}: {exc}", flush=True)
    sys.exit(3)
sizes = comm.gather(comm.Get_size())
if comm.rank == 0:
    c = res.corrections
    out = {"ranks": np.array(sizes), "converged": c.converged, "x": c.x, "on_known": c.on_known,
           "same_as": c.same_as, "seed_branch": res.seed_branch, "kinds": np.array([b.kind for b in res.branches])}
    for k, b in enumerate(res.branches):
        out[f"omega_{k}"], out[f"bx_{k}"] = b.omega, b.x
    np.savez(sys.argv[1], **out)
