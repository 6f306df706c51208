"""The sense of rotation in the time integration, checked by mirror symmetry (as
tests/hbm/test_rotation.py checks the HBM residual).

A blade turning at s Omega and its mirror image (reflected through a meridian plane: each
contact node's angle theta_j -> -theta_j and its tangential dof v_theta -> -v_theta, so
K -> P K P, M -> P M P, C -> P C P with P = diag(1, -1, 1) per node) turning at -s Omega are
the same physical problem seen in a mirror: the radial and axial responses and the normal
forces are equal, the tangential displacements and friction forces opposite. A sense
applied to the casing but not to the friction (or the reverse), or applied twice, breaks
the equality; the same ROM turned the other way must give another response.
"""
import dataclasses

import numpy as np
import pytest

from hbm.options import CasingOptions
from hbm.ti.march import Recording, march, massless_system, rom_modal_system
from support import mirrored_rom, standin_rom

CASING = CasingOptions()
MU = 0.3
OMEGA = 1300.0  # rad/s: the stand-in's tip rubs on both lobes, with impacts and sliding


def _run(rom, scheme, n_rev=4):
    system = rom_modal_system(rom)
    dt = 1e-7
    if scheme == "massless":
        system = massless_system(system, 2.0e4)  # the stand-in's modes above 2e4 rad/s made static
        dt = 1e-6
    n_per_rev = int(round(2 * np.pi / (OMEGA * dt)))
    h = 2 * np.pi / (OMEGA * n_per_rev)
    nb = rom.n_boundary
    # every dof of node 0 (LE) and the last node (TE), 64 samples per revolution
    dofs = np.array([0, 1, 2, 3 * (nb - 1), 3 * (nb - 1) + 1, 3 * (nb - 1) + 2])
    stride = n_per_rev // 64
    rec = Recording(start=stride, stride=stride, n_samples=n_rev * 64 - 1, dofs=dofs, force_nodes=np.arange(nb))
    x0 = np.zeros(rom.n_dof)
    x0[0::3][:nb] = 2e-4  # start pressed outwards: contact from the first steps
    return march(system, CASING, MU, OMEGA, x0, np.zeros(rom.n_dof), h, n_rev * n_per_rev, rec)


@pytest.mark.parametrize("scheme", ["carpenter", "massless"])
def test_mirror_image_turning_the_other_way_in_time(scheme):
    rom = standin_rom(rotation=-1)
    mirrored, _ = mirrored_rom(rom)
    a = _run(rom, scheme)
    b = _run(mirrored, scheme)
    assert a.contact_steps > 0.05 * a.n_steps and a.active_set_failures == 0
    assert np.abs(a.friction_force).max() > 0.1 * MU * np.abs(a.normal_force).max()  # friction acts
    # Sign flips are exact in floating point, so the two marches do the same operations on
    # mirrored numbers (measured: bitwise equal, difference 0). 1e-10 of the largest value
    # leaves room for a LAPACK that rounds the mirrored eigenproblem differently; a sense
    # missing from the friction gives O(1) differences (measured 1.4 of the largest value).
    sign = np.array([1.0, -1.0, 1.0, 1.0, -1.0, 1.0])
    x_scale = np.abs(a.displacement).max(axis=0)
    np.testing.assert_allclose(a.displacement, sign * b.displacement, rtol=0, atol=1e-10 * x_scale.max())
    f_scale = np.abs(a.normal_force).max()
    np.testing.assert_allclose(a.normal_force, b.normal_force, rtol=0, atol=1e-10 * f_scale)
    np.testing.assert_allclose(a.friction_force[..., 0], -b.friction_force[..., 0], rtol=0, atol=1e-10 * f_scale)
    np.testing.assert_allclose(a.friction_force[..., 1], b.friction_force[..., 1], rtol=0, atol=1e-10 * f_scale)
    # the sense matters: the same ROM turning the other way (s = +1) is another response
    c = _run(dataclasses.replace(rom, rotation=1), scheme)
    assert np.abs(c.displacement - a.displacement).max() > 1e-2 * x_scale.max()


def test_friction_opposes_the_blade_speed_in_time():
    # the blade slides at s rho Omega (~300 m/s) >> the vibration velocity: the friction
    # force on the blade is -mu lam s e_theta, sign for sign
    for s in (1, -1):
        m = _run(standin_rom(rotation=s), "carpenter", n_rev=2)
        lam = m.normal_force
        on = lam > 1e-3 * lam.max()
        assert on.sum() > 10
        np.testing.assert_allclose(m.friction_force[..., 0][on], -s * MU * lam[on], rtol=1e-3)
