"""Every array of fem.h5 carries its unit (the project's file layout: arrays carry their
unit in an attribute), the parts of the CSR matrices K and M included: K's entries in N/m,
M's in kg (FemResult's field units), their column indices and row pointers counts ("1").
The file is written as the FEM stage writes it (pipelines.artifacts.write_artifact of a
fem.analysis.FemResult) and still passes the artifact verification."""
import h5py
import numpy as np
import pytest
from box_mesh import box_mesh

from fem.analysis import FemResult, analyse_blade
from fem.material import Material
from fem.options import FemOptions
from pipelines import artifacts as art

EXPECTED = {"K/data": "N/m", "K/indices": "1", "K/indptr": "1",
            "M/data": "kg", "M/indices": "1", "M/indptr": "1"}


@pytest.fixture(scope="module")
def fem_h5(tmp_path_factory):
    mesh = box_mesh(0.05, 0.02, 0.01, 0.008, n_boundary=3)
    result = analyse_blade(mesh, Material(), FemOptions(n_modes=2, n_fixed_interface_modes=2))
    path = tmp_path_factory.mktemp("fem") / "fem.h5"
    art.write_artifact(path, result, stage="fem")
    return path, result


def test_every_dataset_of_fem_h5_has_a_unit(fem_h5):
    path, _ = fem_h5
    with h5py.File(path, "r") as h5:
        found = {}
        h5.visititems(lambda name, obj: found.__setitem__(name, obj.attrs.get("unit"))
                      if isinstance(obj, h5py.Dataset) else None)
    assert found and not [k for k, u in found.items() if u is None], found
    assert {k: found[k] for k in EXPECTED} == EXPECTED


def test_fem_h5_with_units_verifies_and_reads_back(fem_h5):
    path, result = fem_h5
    assert art.verify(path) is None
    back = art.read_artifact(path, FemResult)
    for name in ("K", "M"):
        assert (getattr(back, name) != getattr(result, name)).nnz == 0
