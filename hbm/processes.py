"""The start method of the worker processes that the sweep, the isola search and the hbm
stage spread their independent tasks over."""
from __future__ import annotations

import multiprocessing
import sys


def process_context():
    """multiprocessing context: "fork" (cheapest: workers inherit the compiled kernels and
    the built residuals) unless MPI is initialised in this process (dolfinx does it in the
    fem stage; mpi4py's state does not survive a fork), then "spawn"."""
    return multiprocessing.get_context("spawn" if "mpi4py.MPI" in sys.modules else "fork")
