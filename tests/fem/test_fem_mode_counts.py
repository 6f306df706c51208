"""Mode counts beyond the clamped model's dof are refused by name before K is factorised
(minutes on a blade), not by the eigen-solver once the full-model modes are computed."""
import pytest
from box_mesh import box_mesh

import fem.cholesky
from fem.analysis import analyse_blade
from fem.assembly import assemble_system
from fem.material import Material
from fem.options import FemOptions


@pytest.fixture(scope="module")
def box():
    mesh = box_mesh(0.05, 0.02, 0.01, 0.02, n_boundary=3)
    n_free = assemble_system(mesh.nodes, mesh.cells, mesh.root_facets, Material()).K.shape[0]
    return mesh, n_free


def _no_factorisation(monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError("K was factorised before the count was checked")
    monkeypatch.setattr(fem.cholesky, "CholeskyFactor", refuse)


def test_too_many_fixed_interface_modes_are_refused_before_the_factorisation(box, monkeypatch):
    mesh, n_free = box
    interior = n_free - 3 * 3  # 3 boundary nodes, 3 dof each
    _no_factorisation(monkeypatch)
    with pytest.raises(ValueError, match=rf"n_fixed_interface_modes.*\[rom\] n_fixed_modes\) = {interior + 1}, "
                                         rf"but the fixed-interface problem has only {interior} modes"):
        analyse_blade(mesh, Material(), FemOptions(n_modes=2, n_fixed_interface_modes=interior + 1))


def test_too_many_modes_are_refused_before_the_factorisation(box, monkeypatch):
    mesh, n_free = box
    _no_factorisation(monkeypatch)
    with pytest.raises(ValueError, match=rf"\[fem\] n_modes = {n_free + 1}, but the clamped model has only "
                                         rf"{n_free} dof"):
        analyse_blade(mesh, Material(), FemOptions(n_modes=n_free + 1, n_fixed_interface_modes=2))


def test_the_largest_counts_are_computed(box):
    mesh, n_free = box
    interior = n_free - 9
    r = analyse_blade(mesh, Material(), FemOptions(n_modes=n_free, n_fixed_interface_modes=interior))
    assert r.frequencies.shape == (n_free,) and r.fixed_interface_modes.shape == (n_free, interior)
