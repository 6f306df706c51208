"""Run under `mpirun -n 2` by test_time_integration_sweep.test_mpi_sweep_equals_the_serial_one:
the sweep of MPI_OPTIONS over MPI_OMEGAS of the ModalSystem saved in argv[1]; rank 0 saves
the result to argv[2]. With argv[3] = "fail", keeping rank 1's first speed raises OSError
(test_a_failing_rank_ends_the_mpi_sweep_on_every_rank): each rank prints what it raised
and exits 3."""
import sys

import numpy as np
from mpi4py import MPI

from hbm.options import CasingOptions, ContactOptions
from hbm.ti.march import ModalSystem
from hbm.ti.sweep import sweep
from test_time_integration_sweep import MPI_OMEGAS, MPI_OPTIONS

comm = MPI.COMM_WORLD
system = ModalSystem(**dict(np.load(sys.argv[1])))


def keep(i, response):
    if comm.rank == 1:
        raise OSError(28, "No space left on device")


failing = sys.argv[3:] == ["fail"]
try:
    res = sweep(system, CasingOptions(), ContactOptions(), MPI_OPTIONS, omegas=MPI_OMEGAS,
                on_speed=keep if failing else None)
except Exception as exc:  # noqa: BLE001 - what each rank raised, for the test
    print(f"rank {comm.rank} raised {type(exc).__name__}: {exc}", flush=True)
    sys.exit(3)
sizes = comm.gather(comm.Get_size())
if comm.rank == 0:
    np.savez(sys.argv[2], ranks=np.array(sizes), **{k: getattr(res, k) for k in
             ("omega", "amplitude", "period_class", "revolutions", "displacement", "normal_force", "sections")})
