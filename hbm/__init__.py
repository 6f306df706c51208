"""The nonlinear side: harmonic balance and time integration of a reduced blade model rubbing
a rigid casing. Plain numpy/scipy (and numba for the time-integration kernel); never the FE
stack, so a ROM from any FE code can be used (see rom.model.RomModel for the layout).

Layers, lowest first (import-linter contracts in pyproject.toml):

- hbm.linalg: the LinearSolver protocol the solvers use, direct solves, GMRES, the bordered
  system of the arc-length corrector, SingularMatrixError. A leaf.
- hbm.continuation: the one Newton loop, arc-length continuation of any residual(x, omega)
  -> (R, dR/dx, dR/domega) with a LinearSolver, branches. Knows nothing of contact.
- hbm.contact: the casing of eq. (28), the normal laws (DLFT correction, regularised
  penalty) and sliding friction, on time samples only; shared by HBM and time integration.
- hbm.harmonic: the Fourier basis and AFT, the exact condensation on the contact dof, the
  residual, its structured Jacobian and solver, start strategies, the NFRC.
- hbm.ti: time integration with exact Lagrange-multiplier contact, the speed sweep,
  periodicity classes, and marching from HBM solutions (validation).

Design choices a maintainer should know (the measured reasons are in the docstrings):
the HBM Jacobian is never factorised densely (hbm.harmonic.jacobian, preconditioner, solver);
the corrector's linear solves are inexact Newton steps (hbm.harmonic.solver); the casing law
exists once for both solvers (hbm.contact.casing); numba's code is tuned for Zen 2 on a
host LLVM 14 calls Zen 3, whose model unrolls the time-integration kernel into a slower one
(hbm.jit, done here so that it precedes any compile of a bladerub run); OpenBLAS runs its
AVX2 or AVX-512 kernels on a CPU its tables do not know, where it would run its oldest ones
(hbm.openblas, done here so that it precedes numpy in a process that imports hbm first: the
bladerub command and the tests do); and an MPI singleton, outside mpirun, starts no helper
daemon (hbm.processes.isolate_mpi_singleton, before dolfinx initialises MPI).
"""
from hbm.jit import retune_numba
from hbm.openblas import choose_openblas_core
from hbm.processes import isolate_mpi_singleton

retune_numba()
choose_openblas_core()
isolate_mpi_singleton()
