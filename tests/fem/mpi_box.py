"""Worker of test_mpi_box_s10 (run under `mpirun -n 2`): the FEM stage of a small clamped
box on the ranks and, on rank 0, in one process; rank 0 saves both results to an .npz.

argv: ARRANGEMENT OUT. ARRANGEMENT "first" numbers the contact nodes before every other
node, "last" after: the serial free-dof numbering, split at the middle over two ranks,
then puts every contact dof on rank 0, or on rank 1, and the other rank holds none.
"""
import sys
from pathlib import Path

import numpy as np
from mpi4py import MPI

sys.path.insert(0, str(Path(__file__).resolve().parent))  # box_mesh

from box_mesh import box_mesh  # noqa: E402
from fem.analysis import solve_system  # noqa: E402
from fem.assembly import assemble_distributed, assemble_system  # noqa: E402
from fem.material import Material  # noqa: E402
from fem.options import FemOptions  # noqa: E402

NAMES = ("frequencies", "fixed_interface_frequencies", "modes", "constraint_modes",
         "fixed_interface_modes", "residuals")


def renumbered(box, arrangement: str):
    """(nodes, cells, root_facets, boundary nodes) with the contact nodes numbered first or last."""
    n = box.n_nodes
    contact = np.zeros(n, dtype=bool)
    contact[box.boundary_node_index] = True
    rest = np.flatnonzero(~contact)
    order = np.concatenate([np.flatnonzero(contact), rest] if arrangement == "first" else [rest, np.flatnonzero(contact)])
    new = np.empty(n, dtype=np.int64)
    new[order] = np.arange(n)
    return box.nodes[order], new[box.cells], new[box.root_facets], new[box.boundary_node_index]


def main(arrangement: str, out: str) -> None:
    comm = MPI.COMM_WORLD
    box = comm.bcast(box_mesh(0.08, 0.02, 0.01, 0.005, n_boundary=3) if comm.rank == 0 else None)
    nodes, cells, root, contact = renumbered(box, arrangement)
    options = FemOptions(n_modes=6, n_fixed_interface_modes=6)
    system = assemble_distributed(nodes, cells, root, Material(), comm)
    layout = system.layout
    bd = system.node_dofs[contact].ravel()
    held = comm.gather(int(((bd >= layout.start) & (bd < layout.stop)).sum()), root=0)
    try:
        par = solve_system(system, options, contact)
    finally:
        system.destroy()
    if comm.rank == 0:
        ser = solve_system(assemble_system(nodes, cells, root, Material()), options, contact)
        arrays = {"contact_dof_per_rank": np.asarray(held)}
        for tag, r in (("par", par), ("ser", ser)):
            for name in NAMES:
                arrays[f"{tag}_{name}"] = getattr(r, name)
            for name in ("K", "M"):  # CSR parts: the dense matrices would be ~100 MB each
                A = getattr(r, name)
                for part in ("indptr", "indices", "data"):
                    arrays[f"{tag}_{name}_{part}"] = getattr(A, part)
        np.savez(out, **arrays)


if __name__ == "__main__":
    main(*sys.argv[1:3])
