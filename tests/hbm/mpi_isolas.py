"""Run under `mpirun -n 2` by test_isolas.test_mpi_search_equals_the_serial_one: the search of
test_isolas (modal seeds, the primary as known branch) with the seeds shared among the
ranks; rank 0 saves the result to argv[1]."""
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
res = search(factory, modal_seeds(), [primary], options(), comm=comm)
sizes = comm.gather(comm.Get_size())
if comm.rank == 0:
    c = res.corrections
    out = {"ranks": np.array(sizes), "converged": c.converged, "x": c.x, "on_known": c.on_known,
           "same_as": c.same_as, "seed_branch": res.seed_branch, "kinds": np.array([b.kind for b in res.branches])}
    for k, b in enumerate(res.branches):
        out[f"omega_{k}"], out[f"bx_{k}"] = b.omega, b.x
    np.savez(sys.argv[1], **out)
