"""Linear-elastic stiffness and consistent mass of a quadratic tetrahedral mesh, root clamped.

dolfinx builds and assembles the P2 vector Lagrange system on the tet10 geometry; the
result is handed on as scipy CSR matrices of the free (unclamped) dof, ordered node-major
in mesh node order, so that later stages need neither dolfinx nor its dof numbering.
Under MPI (`assemble_distributed`) the same matrices stay spread over the ranks, in the
same numbering, for the distributed factorisation.
"""
from __future__ import annotations

import logging
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from fem.material import Material


@dataclass(frozen=True)
class FemSystem:
    """Free-dof stiffness and mass of the clamped blade.

    K: stiffness, (n_free, n_free) scipy CSR, N/m. M: consistent mass, (n_free, n_free) CSR, kg.
        (fem.analysis also holds them as fem.symmetric.SymmetricMatrix, their upper triangles.)
    node_dofs: (n_nodes, 3) int64, free-dof index of each mesh node's x, y, z
        displacement, -1 on clamped (root) nodes. Free dof are numbered node-major in mesh
        node order: node_dofs[node_dofs >= 0] == arange(n_free).
    """

    K: sp.csr_matrix = field(metadata={"unit": "N/m"})
    M: sp.csr_matrix = field(metadata={"unit": "kg"})
    node_dofs: np.ndarray = field(metadata={"unit": "1"})

    @property
    def n_free(self) -> int:
        return int(self.K.shape[0])

    @property
    def n_nodes(self) -> int:
        return int(self.node_dofs.shape[0])

    def to_nodal(self, u: np.ndarray) -> np.ndarray:
        """Free-dof vectors (n_free,) or (n_free, k) -> nodal (n_nodes, 3) or (k, n_nodes, 3), m.

        Clamped nodes get 0.
        """
        u = np.asarray(u)
        if u.shape[0] != self.n_free:
            raise ValueError(f"expected {self.n_free} free dof, got array of shape {u.shape}")
        flat = u.reshape(self.n_free, -1)
        out = np.zeros((flat.shape[1], self.n_nodes, 3), dtype=u.dtype)
        free = self.node_dofs[:, 0] >= 0
        out[:, free] = flat.T.reshape(flat.shape[1], -1, 3)  # free dof are node-major
        return out[0] if u.ndim == 1 else out


def _check_mesh(nodes: np.ndarray, cells: np.ndarray, root_facets: np.ndarray) -> None:
    if nodes.ndim != 2 or nodes.shape[1] != 3:
        raise ValueError(f"nodes must have shape (n, 3), got {nodes.shape}")
    if cells.ndim != 2 or cells.shape[1] != 10:
        raise ValueError(f"cells must be tet10 connectivity of shape (n_cells, 10), got {cells.shape}")
    if len(cells) == 0:
        raise ValueError("the mesh has no cells")
    if root_facets is None or np.size(root_facets) == 0:
        raise ValueError("the mesh has no root facets: the blade would be unclamped "
                         "(singular stiffness); BladeMesh.root_facets must list the clamped root face")
    # tri6 only: a tri3 (corners only) would leave the root's mid-edge nodes free, a
    # partly clamped root whose frequencies come out ~20 % low without a word
    if root_facets.ndim != 2 or root_facets.shape[1] != 6:
        raise ValueError(f"root_facets must be tri6 connectivity of shape (n_root, 6), got {root_facets.shape}")
    n = len(nodes)
    for name, a in (("cells", cells), ("root_facets", root_facets)):
        if a.min() < 0 or a.max() >= n:
            raise ValueError(f"{name} refer to nodes outside 0..{n - 1}")
    used = np.zeros(n, dtype=bool)
    used[cells.ravel()] = True
    if not used.all():
        raise ValueError(f"{int((~used).sum())} nodes belong to no cell (their dof would be singular)")
    _check_clamp_holds(nodes, cells, root_facets)


def _rigid_pieces(cells: np.ndarray) -> tuple[int, np.ndarray]:
    """(count, piece of each cell (n_cells,)): the cells joined through shared faces. Two
    tetrahedra that share a face (three corners, never collinear) move as one body; cells
    that share only an edge or a node may still turn about it (a hinge, a ball joint)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    corners = np.sort(cells[:, :4], axis=1)
    faces = corners[:, [[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]]].reshape(-1, 3)  # sorted triples
    owner = np.repeat(np.arange(len(cells)), 4)
    order = np.lexsort(faces.T[::-1])
    faces, owner = faces[order], owner[order]
    shared = np.all(faces[1:] == faces[:-1], axis=1)
    a, b = owner[:-1][shared], owner[1:][shared]
    graph = coo_matrix((np.ones(len(a), dtype=np.int8), (a, b)), shape=(len(cells), len(cells)))
    return connected_components(graph, directed=False)


def _spans_a_plane(x: np.ndarray, size: float) -> bool:
    """True if the points (k, 3), m, are not all on one line (to 1e-9 of the mesh size, m):
    pinned there, a body keeps no rigid-body motion."""
    if len(x) < 3:
        return False
    return bool(np.linalg.svd(x - x.mean(axis=0), compute_uv=False)[1] > 1e-9 * size)


def _check_clamp_holds(nodes: np.ndarray, cells: np.ndarray, root_facets: np.ndarray) -> None:
    """Every rigid piece of the mesh (cells joined through faces, _rigid_pieces) must be held:
    by clamped nodes not all on one line, or by nodes not all on one line that it shares
    with pieces already held. Otherwise a rigid-body motion (the rotation about that line,
    or the whole piece) is left free, K is singular, and the factorisation may pass on
    round-off pivots: a zero-frequency "mode" (seen: 1e-3 Hz, residual 1, with a two-node
    root; a piece hung on the rest by one line of nodes gave 2e-3 Hz with CHOLMOD and no
    convergence in 40 block steps with MUMPS)."""
    from scipy.sparse import csr_matrix

    n_pieces, piece = _rigid_pieces(cells)
    n = len(nodes)
    size = np.ptp(nodes, axis=0).max()
    # piece-node incidence (n_pieces, n): the nodes of each piece, and the pieces of each node
    keys = np.unique(np.repeat(piece.astype(np.int64), cells.shape[1]) * n + cells.ravel())
    incidence = csr_matrix((np.ones(len(keys), dtype=np.int8), (keys // n, keys % n)), shape=(n_pieces, n))
    pieces_of = incidence.T.tocsr()
    held = np.zeros(n, dtype=bool)
    held[root_facets.ravel()] = True
    loose = np.ones(n_pieces, dtype=bool)
    # a worklist: a piece is looked at again only when a neighbour (sharing a node) got held
    todo = list(range(n_pieces))
    while todo:
        p = todo.pop()
        if not loose[p]:
            continue
        mine = incidence.indices[incidence.indptr[p]:incidence.indptr[p + 1]]
        if _spans_a_plane(nodes[mine[held[mine]]], size):
            loose[p] = False
            held[mine] = True
            touched = np.unique(pieces_of[mine].indices)
            todo.extend(touched[loose[touched]].tolist())
    if loose.any():
        p = int(np.flatnonzero(loose)[0])
        mine = incidence.indices[incidence.indptr[p]:incidence.indptr[p + 1]]
        where = "the mesh" if n_pieces == 1 else (
            f"{int(loose.sum())} of its {n_pieces} pieces (cells joined through faces; the first has "
            f"{int((piece == p).sum())} cells and {len(mine)} nodes)")
        pinned = int(held[mine].sum())
        raise ValueError(f"the root clamp leaves {where} free to move as a rigid body: it is held at {pinned} "
                         "nodes, all on one line or none (singular stiffness); the root facets must cover a face, "
                         "and a piece joined to the rest only along an edge or at a node turns about it")


def _to_scipy(A) -> sp.csr_matrix:
    """PETSc AIJ -> scipy CSR (copy), then the PETSc matrix is destroyed to free memory."""
    indptr, indices, data = A.getValuesCSR()
    out = sp.csr_matrix((data, indices, indptr), shape=A.getSize())
    A.destroy()
    return out


def _restrict(A: sp.csr_matrix, order: np.ndarray) -> sp.csr_matrix:
    """A[order][:, order] for a square CSR A, without scipy's column fancy-indexing (which
    builds an index matrix product; ~3x slower on 5e7 nonzeros): gather the rows, renumber
    the column indices through the inverse map, drop the removed (clamped) columns."""
    inv = np.full(A.shape[1], -1, dtype=np.int64)
    inv[order] = np.arange(len(order))
    B = A[order]
    del A
    cols = inv[B.indices]
    keep = cols >= 0
    counts = np.add.reduceat(keep, B.indptr[:-1]) if B.nnz else np.zeros(B.shape[0], dtype=np.int64)
    counts[np.diff(B.indptr) == 0] = 0  # reduceat repeats the next value for empty rows
    indptr = np.concatenate([[0], np.cumsum(counts)])
    out = sp.csr_matrix((B.data[keep], cols[keep].astype(np.int32), indptr.astype(np.int32)),
                        shape=(len(order), len(order)))
    out.sort_indices()
    return out


def _warnings_only(record: logging.LogRecord) -> bool:
    return record.levelno >= logging.WARNING


@contextmanager
def _quiet_compiler_log():
    """Keep the compiler's command lines of a first run off the terminal.

    ffcx calls logging.basicConfig() when imported (a handler on the root logger that
    prints whatever reaches it), and compiles each new element and form with cffi, whose
    build (setuptools' distutils) raises the root logger's level to INFO and logs every
    compiler call there: nine lines in the middle of the fem stage's report on a first run
    (ffcx caches what it compiled). A filter on the root logger for the compile's duration
    drops what is logged to it below WARNING; warnings, and other loggers, go through.
    """
    root = logging.getLogger()
    root.addFilter(_warnings_only)
    try:
        yield
    finally:
        root.removeFilter(_warnings_only)


@_quiet_compiler_log()
def _dolfinx_problem(nodes: np.ndarray, cells: np.ndarray, material: Material, comm):
    """dolfinx mesh on `comm` (rank 0 gives all cells, the partitioner distributes them),
    the compiled K and M forms, and (node (k,), block (k,)): the dolfinx global block dof
    of the mesh nodes whose dof this rank owns (repeated once per cell; every node is
    owned by exactly one rank)."""
    import ufl
    from dolfinx import fem, mesh as dmesh
    # perm_gmsh, not dolfinx.io.gmshio: that imports gmsh, and importing gmsh sets SIGINT to
    # its default action for the whole process (Ctrl-C would then kill a run without a word)
    from dolfinx.cpp.io import perm_gmsh

    # gmsh tet10 (edges 01,12,20,30,32,31) -> dolfinx local ordering
    perm = perm_gmsh(dmesh.CellType.tetrahedron, 10)
    domain = ufl.Mesh(ufl.VectorElement(ufl.FiniteElement("Lagrange", ufl.tetrahedron, 2,
                                                          variant="equispaced")))
    if comm.rank != 0:  # all cells come from rank 0; the others join with empty arrays
        cells, nodes = np.empty((0, 10), dtype=np.int64), np.empty((0, 3))
    msh = dmesh.create_mesh(comm, cells[:, perm], nodes, domain)

    V = fem.VectorFunctionSpace(msh, ("Lagrange", 2))
    lmbda, mu = material.lame
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)

    def eps(w):
        return ufl.sym(ufl.grad(w))

    a_k = (2 * mu * ufl.inner(eps(u), eps(v)) + lmbda * ufl.div(u) * ufl.div(v)) * ufl.dx
    a_m = material.rho * ufl.inner(u, v) * ufl.dx

    # Mesh node -> dolfinx block dof. The P2 space and the P2 coordinate element share the
    # local (basix) ordering, so cell-wise the geometry dofs and the space's dofs coincide;
    # input_global_indices maps dolfinx's geometry nodes back to the input (mesh) numbering.
    gdofs = msh.geometry.dofmap.array
    vdofs = V.dofmap.list.array
    input_index = np.asarray(msh.geometry.input_global_indices, dtype=np.int64)
    imap = V.dofmap.index_map
    owned = vdofs < imap.size_local  # a node is owned by exactly one rank
    node = input_index[gdofs[owned]]
    block = imap.local_to_global(vdofs[owned].astype(np.int32)).astype(np.int64)
    return (fem.form(a_k), fem.form(a_m)), node, block


def _clamp(n_nodes: int, root_facets: np.ndarray) -> np.ndarray:
    """node_dofs (n_nodes, 3): node-major free-dof numbering, -1 on the root-facet nodes."""
    clamped = np.zeros(n_nodes, dtype=bool)
    clamped[root_facets.ravel()] = True
    node_dofs = np.full((n_nodes, 3), -1, dtype=np.int64)
    node_dofs[~clamped] = np.arange(3 * int((~clamped).sum())).reshape(-1, 3)
    return node_dofs


def _checked(nodes, cells, root_facets, material):
    nodes = np.ascontiguousarray(nodes, dtype=np.float64)
    cells = np.asarray(cells, dtype=np.int64)
    root_facets = np.asarray(root_facets, dtype=np.int64) if root_facets is not None else None
    _check_mesh(nodes, cells, root_facets)
    if not isinstance(material, Material):
        raise TypeError(f"material must be a fem.material.Material, got {type(material).__name__}")
    return nodes, cells, root_facets


def assemble_system(nodes: np.ndarray, cells: np.ndarray, root_facets: np.ndarray,
                    material: Material) -> FemSystem:
    """Assemble K and M of linear elasticity on a tet10 mesh with all root-facet nodes clamped.

    nodes: (n, 3), m. cells: (n_cells, 10) tet10 in gmsh node ordering.
    root_facets: (n_root, 6) tri6 (gmsh ordering) of the clamped face; every node on them
    has its 3 dof removed. material: E (Pa), nu, rho (kg/m^3).
    Serial (COMM_SELF): the matrices are returned whole to this process.
    """
    from mpi4py import MPI
    from dolfinx.fem.petsc import assemble_matrix

    nodes, cells, root_facets = _checked(nodes, cells, root_facets, material)
    forms, node, blk = _dolfinx_problem(nodes, cells, material, MPI.COMM_SELF)
    block = np.empty(len(nodes), dtype=np.int64)
    block[node] = blk
    node_dofs = _clamp(len(nodes), root_facets)
    free = node_dofs[:, 0] >= 0
    # dolfinx dof (blocked, bs = 3) of each free dof, in the node-major order above
    order = (3 * block[free, None] + np.arange(3)).ravel()

    mats = []
    for a in forms:
        A = assemble_matrix(a)
        A.assemble()
        mats.append(_restrict(_to_scipy(A), order))
    K, M = mats
    return FemSystem(K=K, M=M, node_dofs=node_dofs)


@dataclass(frozen=True)
class DistributedSystem:
    """K and M of the clamped blade spread over the ranks of an MPI communicator.

    K, M: fem.distributed.DistributedMatrix, (n_free, n_free) globally, N/m and kg, in the
        serial free-dof numbering (the node_dofs of FemSystem), rows split over the ranks
        as `layout` says.
    node_dofs: (n_nodes, 3), the same on every rank and equal to the serial one.
    layout: fem.distributed.Distributed.
    """

    K: object = field(metadata={"unit": "N/m"})
    M: object = field(metadata={"unit": "kg"})
    node_dofs: np.ndarray = field(metadata={"unit": "1"})
    layout: object = None

    @property
    def n_free(self) -> int:
        return int(self.K.shape[0])

    def gather(self) -> FemSystem | None:
        """The whole system as scipy CSR on rank 0 (what `assemble_system` returns there);
        None on the other ranks. Collective."""
        K, M = self.K.gather_csr(), self.M.gather_csr()
        return FemSystem(K=K, M=M, node_dofs=self.node_dofs) if K is not None else None

    def destroy(self) -> None:
        self.K.destroy()
        self.M.destroy()


def assemble_distributed(nodes: np.ndarray, cells: np.ndarray, root_facets: np.ndarray,
                         material: Material, comm) -> DistributedSystem:
    """`assemble_system` on the ranks of `comm` (collective; every rank passes the same mesh).

    dolfinx partitions the mesh (rank 0's cells, distributed by its default partitioner)
    and assembles K and M in its own dof numbering; they are then permuted, free dof only,
    into the serial numbering with a contiguous block of free nodes per rank (one
    PETSc MatCreateSubMatrix each, which moves the rows between ranks).
    """
    from petsc4py import PETSc
    from dolfinx.fem.petsc import assemble_matrix

    from fem.distributed import Distributed, DistributedMatrix

    nodes, cells, root_facets = _checked(nodes, cells, root_facets, material)
    forms, node, blk = _dolfinx_problem(nodes, cells, material, comm)
    # every rank learns the dolfinx block of every node (n_nodes integers)
    block = np.full(len(nodes), -1, dtype=np.int64)
    for n_, b_ in comm.allgather((node, blk)):
        block[n_] = b_
    if (block < 0).any():
        raise RuntimeError(f"{int((block < 0).sum())} mesh nodes got no dof in the distributed mesh")
    node_dofs = _clamp(len(nodes), root_facets)
    free_nodes = np.flatnonzero(node_dofs[:, 0] >= 0)
    lo = len(free_nodes) * comm.rank // comm.size
    hi = len(free_nodes) * (comm.rank + 1) // comm.size
    layout = Distributed(comm, 3 * len(free_nodes), 3 * lo, 3 * hi)
    rows = (3 * block[free_nodes[lo:hi], None] + np.arange(3)).ravel().astype(PETSc.IntType)
    index = PETSc.IS().createGeneral(rows, comm=comm)
    mats = []
    for a in forms:
        A = assemble_matrix(a)
        A.assemble()
        mats.append(DistributedMatrix(A.createSubMatrix(index, index), layout))
        A.destroy()
    index.destroy()
    K, M = mats
    return DistributedSystem(K=K, M=M, node_dofs=node_dofs, layout=layout)
