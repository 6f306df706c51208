"""The FEM stage: BladeMesh -> assembled, clamped system, full-model modes and the
Craig-Bampton ingredients, all from one Cholesky factorisation of K (see fem.interface)."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from fem.assembly import FemSystem, assemble_system
from fem.material import Material
from fem.options import FemOptions


@dataclass(frozen=True)
class FemResult:
    """What fem.h5 holds.

    K: (n_free, n_free) CSR stiffness, N/m. M: (n_free, n_free) CSR consistent mass, kg.
    node_dofs: (n_nodes, 3) free-dof index of each node's x, y, z; -1 on the clamped root.
    frequencies: (n_modes,) full-model eigenfrequencies, rad/s. frequencies_hz: same, Hz.
    modes: (n_modes, n_nodes, 3) mass-normalised mode shapes at the mesh nodes, global
        x, y, z, kg^-1/2 (0 on the root); for rendering and comparison.
    residuals: (n_modes,) relative residuals of the eigenpairs.
    boundary_node_index: (n_b,) mesh nodes of the interface basis (the contact nodes).
    boundary_dofs: (3 n_b,) their free dof, node-major x, y, z.
    constraint_modes: (n_free, 3 n_b) static response to unit boundary displacements
        (global x, y, z), m/m. fixed_interface_modes: (n_free, eta_max), kg^-1/2.
    fixed_interface_frequencies: (eta_max,), rad/s.
    """

    K: sp.csr_matrix = field(metadata={"unit": "N/m"})
    M: sp.csr_matrix = field(metadata={"unit": "kg"})
    node_dofs: np.ndarray = field(metadata={"unit": "1"})
    frequencies: np.ndarray = field(metadata={"unit": "rad/s"})
    frequencies_hz: np.ndarray = field(metadata={"unit": "Hz"})
    modes: np.ndarray = field(metadata={"unit": "kg^-0.5"})
    residuals: np.ndarray = field(metadata={"unit": "1"})
    boundary_node_index: np.ndarray = field(metadata={"unit": "1"})
    boundary_dofs: np.ndarray = field(metadata={"unit": "1"})
    constraint_modes: np.ndarray = field(metadata={"unit": "m/m"})
    fixed_interface_modes: np.ndarray = field(metadata={"unit": "kg^-0.5"})
    fixed_interface_frequencies: np.ndarray = field(metadata={"unit": "rad/s"})

    @property
    def system(self) -> FemSystem:
        return FemSystem(K=self.K, M=self.M, node_dofs=self.node_dofs)


def solve_system(system, options: FemOptions, boundary_node_index: np.ndarray | None,
                 timings: dict | None = None) -> FemResult | None:
    """Modes and interface basis of an assembled system (one factorisation of K).

    system: fem.assembly.FemSystem (all on this process; K and M scipy sparse or
        fem.symmetric.SymmetricMatrix, which lets the caller free the whole matrices: the
        result holds them again as CSR), or DistributedSystem: then the
        call is collective over its ranks, K is factorised by MUMPS in parallel, and the
        result comes back whole, in the serial numbering, on rank 0 (None on the others).
    boundary_node_index: (n_b,) mesh nodes for the Craig-Bampton basis; None or empty skips it.
    timings: if a dict, receives wall times in s of 'factorisation', 'modes', 'interface'
        (and 'gather' under MPI) and the block-solve counts 'modes_block_solves',
        'interface_block_solves'; 'solver', the package that factorised K, and 'ordering', the
        fill-reducing ordering it applied (fem.cholesky.CholeskyFactor.solver_used,
        .ordering_used); out of core, 'factor_files_mb', the size of the factor's files
        under TMPDIR, MB.
    """
    import tempfile
    import time

    from fem.assembly import DistributedSystem
    from fem.cholesky import CholeskyFactor
    from fem.interface import boundary_dofs_of, check_fixed_mode_count, compute_interface_basis
    from fem.memory import return_freed_memory
    from fem.modes import compute_modes
    from fem.symmetric import SymmetricMatrix

    timings = {} if timings is None else timings
    layout = system.layout if isinstance(system, DistributedSystem) else None
    K, M = system.K, system.M
    want_basis = boundary_node_index is not None and len(boundary_node_index) > 0
    bd = boundary_dofs_of(system.node_dofs, boundary_node_index) if want_basis else np.zeros(0, np.int64)
    # before the factorisation (minutes on a blade), not after the modes
    n_free = int(K.shape[0])
    if not 1 <= options.n_modes <= n_free:
        raise ValueError(f"[fem] n_modes = {options.n_modes}, but the clamped model has only {n_free} dof: "
                         f"allowed 1..{n_free}")
    if want_basis:
        check_fixed_mode_count(options.n_fixed_interface_modes, n_free, len(bd),
                               "n_fixed_modes (the fem stage's max of [fem] n_fixed_interface_modes, "
                               "[rom] n_fixed_modes)")
    scratch = tempfile.TemporaryDirectory(prefix="bladerub-mumps-") if options.out_of_core else None
    waiting = None
    M_solve = M
    if layout is None:
        # In one process K and M are held as upper triangles (fem.symmetric), and wait on
        # disk from the factorisation on: K is read from its file for the residuals only,
        # M for fem.h5 at the end; the eigen-solves multiply by M without its structural
        # zeros (two thirds of its entries; a quarter faster), read back once K is factorised.
        K, M = (A if isinstance(A, SymmetricMatrix) else SymmetricMatrix.from_csr(A) for A in (K, M))
        waiting = tempfile.TemporaryDirectory(prefix="bladerub-fem-")
        for name, A in (("K", K), ("M", M)):
            (Path(waiting.name) / name).mkdir()
            A.spill(Path(waiting.name) / name)
    t = time.perf_counter()
    try:
        factor = CholeskyFactor(K, ordering=options.ordering, out_of_core=scratch.name if scratch else None,
                                solver=options.solver)
    except BaseException:
        for folder in (scratch, waiting):
            if folder is not None:
                folder.cleanup()
        raise
    timings["factorisation"] = time.perf_counter() - t
    timings["solver"] = factor.solver_used
    timings["ordering"] = factor.ordering_used
    if scratch is not None:  # what the factor takes on the disk of TMPDIR, all ranks together
        files = sum(f.stat().st_size for f in Path(scratch.name).rglob("*") if f.is_file())
        timings["factor_files_mb"] = round((layout.comm.allreduce(files) if layout is not None else files) / 1e6)
    try:
        if waiting is not None:
            M_solve = M.without_zeros()
        t = time.perf_counter()
        modal = compute_modes(K, M_solve, options.n_modes, factor=factor, tol=options.tol, layout=layout)
        timings["modes"] = time.perf_counter() - t
        timings["modes_block_solves"] = modal.n_solves
        return_freed_memory()  # the eigen-solve's small temporaries, kept by the allocator (fem.memory)
        t = time.perf_counter()
        if want_basis:
            basis = compute_interface_basis(K, M_solve, bd, options.n_fixed_interface_modes, factor,
                                            start=modal.vectors, tol=options.tol, layout=layout)
            psi, phi, wfi = basis.constraint_modes, basis.fixed_interface_modes, basis.fixed_interface_frequencies
            timings["interface_block_solves"] = basis.n_solves
        else:
            psi, phi, wfi = np.zeros((K.shape[0], 0)), np.zeros((K.shape[0], 0)), np.zeros(0)
        timings["interface"] = time.perf_counter() - t
    finally:
        factor.destroy()
        if scratch is not None:
            scratch.cleanup()
        if waiting is not None:  # whole matrices for fem.h5, now that the factor is gone
            try:
                K, M = K.to_csr(), M.to_csr()
            finally:
                waiting.cleanup()
    vectors = modal.vectors
    if layout is not None:
        # everything to rank 0, in the serial numbering the row blocks already use
        t = time.perf_counter()
        vectors = layout.gather(vectors)
        if want_basis:
            psi, phi = layout.gather(psi), layout.gather(phi)
        system = system.gather()
        timings["gather"] = time.perf_counter() - t
        if system is None:
            return None
        K, M = system.K, system.M
    return FemResult(K=K, M=M, node_dofs=system.node_dofs, frequencies=modal.frequencies,
                     frequencies_hz=modal.frequencies_hz, modes=system.to_nodal(vectors),
                     residuals=modal.residuals,
                     boundary_node_index=np.asarray(boundary_node_index if want_basis else [], dtype=np.int64),
                     boundary_dofs=bd, constraint_modes=psi, fixed_interface_modes=phi,
                     fixed_interface_frequencies=wfi)


def analyse_blade(mesh, material: Material, options: FemOptions = FemOptions(),
                  timings: dict | None = None, comm=None) -> FemResult | None:
    """The FEM stage on a mesh.model.BladeMesh: assemble (root clamped), factorise K once,
    compute the full-model modes and the interface basis of mesh.boundary_node_index.

    timings: if a dict, receives wall times in s of 'assembly', 'factorisation', 'modes',
        'interface' (and 'gather' under MPI).
    comm: an mpi4py communicator of more than one rank to run distributed (collective:
        every rank passes the same mesh; the result is returned on rank 0, None on the
        others); None or a one-rank communicator: this process alone.
    """
    import time

    from fem.memory import return_freed_memory
    from fem.symmetric import SymmetricMatrix

    timings = {} if timings is None else timings
    t = time.perf_counter()
    if comm is None or comm.size == 1:
        system = assemble_system(mesh.nodes, mesh.cells, mesh.root_facets, material)
        # upper triangles from here on, the whole matrices freed (solve_system)
        system = FemSystem(K=SymmetricMatrix.from_csr(system.K), M=SymmetricMatrix.from_csr(system.M),
                           node_dofs=system.node_dofs)
        return_freed_memory()  # the assembly's temporaries: 2.7 GB on the ~200k deck (fem.memory)
        timings["assembly"] = time.perf_counter() - t
        return solve_system(system, options, mesh.boundary_node_index, timings)
    from fem.assembly import assemble_distributed

    system = assemble_distributed(mesh.nodes, mesh.cells, mesh.root_facets, material, comm)
    timings["assembly"] = time.perf_counter() - t
    try:
        return solve_system(system, options, mesh.boundary_node_index, timings)
    finally:
        system.destroy()
