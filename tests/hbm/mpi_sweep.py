"""Run under `mpirun -n 2` by test_time_integration_sweep.test_mpi_sweep_equals_the_serial_one:
the sweep of MPI_OPTIONS over MPI_OMEGAS of the ModalSystem saved in argv[1]; rank 0 saves
the result to argv[2]."""
import sys

import numpy as np
from mpi4py import MPI

from hbm.options import CasingOptions, ContactOptions
from hbm.ti.march import ModalSystem
from hbm.ti.sweep import sweep
from test_time_integration_sweep import MPI_OMEGAS, MPI_OPTIONS

comm = MPI.COMM_WORLD
system = ModalSystem(**dict(np.load(sys.argv[1])))
res = sweep(system, CasingOptions(), ContactOptions(), MPI_OPTIONS, omegas=MPI_OMEGAS)
sizes = comm.gather(comm.Get_size())
if comm.rank == 0:
    np.savez(sys.argv[2], ranks=np.array(sizes), **{k: getattr(res, k) for k in
             ("omega", "amplitude", "period_class", "revolutions", "displacement", "normal_force", "sections")})
