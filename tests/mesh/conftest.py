"""The coarse rotor 67 table mesh (element_size 8 mm, one element across the edges: ~24 000
nodes, a few seconds), meshed once per test process for every mesh test that reads it."""
import pytest

from mesh.blade import mesh_blade
from mesh.geometry import read_geometry
from mesh.options import BladeOptions, MeshOptions
from support import COARSE_MESH, R67_TABLE as R67

COARSE = MeshOptions(**COARSE_MESH)


@pytest.fixture(scope="session")
def mesh():
    return mesh_blade(BladeOptions(), COARSE, R67)


@pytest.fixture(scope="session")
def geometry():
    return read_geometry(R67, "rotor67", "ft")
