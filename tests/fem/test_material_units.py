"""[material] values in other units than SI, and Poisson's ratios the elements cannot take,
are refused naming the key; real blade materials in SI pass.

A unit slip would otherwise scale every frequency by sqrt of the factor without a word:
E in GPa gives frequencies 3.2e4 times too low, rho in g/cm^3 31.6 times too high.
"""
import pytest

from box_mesh import box_mesh
from fem.assembly import assemble_system
from fem.material import Material
from fem.modes import compute_modes
from pipelines.scene import SceneError, parse_scene

# (E Pa, rho kg/m^3, nu): Ti-6Al-4V, Inconel 718, Al 7075, CFRP quasi-isotropic, PEEK, tungsten
REAL = [(108e9, 4400.0, 0.34), (200e9, 8190.0, 0.29), (71.7e9, 2810.0, 0.33), (70e9, 1600.0, 0.3),
        (3.6e9, 1300.0, 0.4), (411e9, 19250.0, 0.28)]


@pytest.mark.parametrize("E, rho, nu", REAL)
def test_real_blade_materials_in_si_pass(E, rho, nu):
    m = parse_scene(f"[material]\nE = {E!r}\nrho = {rho!r}\nnu = {nu!r}\n").material
    assert (m.E, m.rho, m.nu) == (E, rho, nu)


@pytest.mark.parametrize("text, message", [
    ("E = 108.0", r"\[material\] Young's modulus E must be in Pa.*got 108: in GPa"),  # GPa
    ("E = 108e3", r"\[material\] Young's modulus E must be in Pa.*got 108000"),  # MPa (mm-N-t)
    ("E = 1.08e12\nrho = 4.4", r"\[material\] density rho must be in kg/m\^3.*got 4.4: in g/cm"),  # CGS
    ("rho = 4.4", r"\[material\] density rho must be in kg/m\^3.*got 4.4"),  # g/cm^3
    ("rho = 4.4e-9", r"\[material\] density rho must be in kg/m\^3.*got 4.4e-09"),  # t/mm^3
    ("rho = 0.16", r"\[material\] density rho must be in kg/m\^3"),  # lb/in^3
    ("E = 1e15", r"\[material\] Young's modulus E must be in Pa"),
    ("rho = 4.4e5", r"\[material\] density rho must be in kg/m\^3"),
])
def test_unit_slips_are_refused_naming_the_key(text, message):
    with pytest.raises(SceneError, match=message):
        parse_scene(f"[material]\n{text}\n")


@pytest.mark.parametrize("nu, towards", [(0.4999, "0.5"), (0.49, "0.5"), (-0.9, "-1"), (-0.99, "-1")])
def test_poisson_ratios_where_the_elements_lock_are_refused(nu, towards):
    with pytest.raises(SceneError, match=rf"\[material\] Poisson's ratio nu must lie in.*locks? towards {towards}"):
        parse_scene(f"[material]\nnu = {nu}\n")


@pytest.mark.parametrize("nu", [0.45, 0.0, -0.5])
def test_poisson_ratios_the_elements_take_pass(nu):
    assert parse_scene(f"[material]\nnu = {nu}\n").material.nu == nu


def _unchecked(nu: float) -> Material:
    """Ti-6Al-4V with any nu, past the check (to measure what the check keeps out)."""
    m = Material()
    object.__setattr__(m, "nu", nu)
    return m


def test_the_limit_is_where_locking_starts():
    """First bending of a 0.1 x 0.02 x 0.01 m cantilever on 10x2x1 and 20x4x2 tet10 boxes:
    the coarse mesh's excess over the finer one is the discretisation error. At the limit
    nu = 0.45 it is under 4 times that at nu = 0.3 (measured 3.7); at 0.499 over 8 times
    (measured 10.6: volumetric locking), which the check keeps out."""
    meshes = [box_mesh(0.1, 0.02, 0.01, 0.0, n_boundary=3, transfinite=t) for t in ((10, 2, 1), (20, 4, 2))]

    def first_bending(mesh, nu):
        s = assemble_system(mesh.nodes, mesh.cells, mesh.root_facets, _unchecked(nu))
        return compute_modes(s.K, s.M, 1).frequencies[0]

    def excess(nu):
        return first_bending(meshes[0], nu) / first_bending(meshes[1], nu) - 1

    base = excess(0.3)
    assert 0 < base < 0.02
    assert excess(0.45) < 4 * base
    assert excess(0.499) > 8 * base
