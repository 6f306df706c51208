"""Running the stages under an MPI launcher (`mpirun -n N bladerub run ...`).

One rank (0) does what is serial (meshing, the ROM, HBM, writing artifacts, figures);
all ranks take part in what is distributed (the FEM stage, the time-integration sweep).
The helpers here keep the ranks in step and make a failure on one rank end the run on
all of them with its message, instead of leaving the others waiting forever.
"""
from __future__ import annotations

# the helpers themselves live in hbm.processes: hbm's own collective steps (the sweep, the
# isola search) need them too, and hbm imports nothing of pipelines
from hbm.processes import RankFailed, gathered, idle_barrier, on_all, on_root  # noqa: F401
from hbm.processes import mpi_world as world  # noqa: F401 (the stages' name for it)


def is_root(comm) -> bool:
    return comm is None or comm.rank == 0
