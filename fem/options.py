"""Options of the finite-element stage (scene section [fem])."""
from __future__ import annotations

from dataclasses import dataclass

from fem.cholesky import ORDERINGS, resolve_solver


@dataclass(frozen=True)
class FemOptions:
    """n_modes: number of full-model modes computed and stored (>= 6 for the report).
    n_fixed_interface_modes: fixed-interface modes computed for the ROM stage from the same
        factorisation. The fem stage computes max(this, [rom] n_fixed_modes), so that the
        ROM never factorises K a second time (that would double the dominant cost); a larger
        value keeps modes for ROMs with more of them.
    tol: eigen-solver convergence: largest relative change of a wanted eigenvalue (w^2) in
        the last block step (Ritz values converge monotonically from above).
    solver: the sparse Cholesky (a key of fem.cholesky.SOLVERS): "auto" (default) takes
        CHOLMOD in one process with the factor in memory and MUMPS under MPI or out of
        core; "cholmod" or "mumps" ask for one. CHOLMOD because it factorises 1.45 times
        faster on the ~200k-node wedge deck (97 against 141 s) and ~1.25 times on the
        default blade, with a smaller peak (fem.cholesky); MUMPS because it alone runs
        distributed and out of core.
    ordering: fill-reducing ordering of MUMPS's sparse Cholesky (a key of
        fem.cholesky.ORDERINGS; CHOLMOD keeps the better of AMD and METIS). PORD by default:
        on the default blade's K it needs 6.0e11 flop where AMD needs 1.45e12
        (benchmarks/bench_factor_pattern.py --orderings); METIS and SCOTCH are not in
        Debian's MUMPS (asked for, MUMPS uses its own choice, and the fem stage says so).
    out_of_core: MUMPS keeps the Cholesky factor of K in files (a temporary folder in the
        system's temp directory, TMPDIR) instead of memory, and reads it back at each block
        solve: the peak memory drops by the factor's size, at the cost of writing it once
        and reading it ~20 times (from the page cache when memory allows). Measured on the
        rotor 67 wedge deck of 589 950 dof: peak 4.2 GB instead of 8.8 GB, CPU time 361 s
        instead of 279 s, the same frequencies to 1e-14. Off by default: in core is faster
        where the memory is there (the default blade needs ~4 GB, the ~200k deck ~11).
    """

    n_modes: int = 12
    n_fixed_interface_modes: int = 12
    tol: float = 1e-10
    solver: str = "auto"
    ordering: str = "pord"
    out_of_core: bool = False

    def __post_init__(self):
        if self.n_modes < 1:
            raise ValueError(f"n_modes must be >= 1, got {self.n_modes}")
        if self.n_fixed_interface_modes < 0:
            raise ValueError(f"n_fixed_interface_modes must be >= 0, got {self.n_fixed_interface_modes}")
        if not 0 < self.tol < 1e-2:
            raise ValueError(f"tol must be in (0, 1e-2), got {self.tol}")
        resolve_solver(self.solver, distributed=False, out_of_core=self.out_of_core)  # its rules, in one place
        if self.ordering not in ORDERINGS:
            raise ValueError(f"unknown ordering '{self.ordering}'; known: {', '.join(ORDERINGS)}")
