"""The sense of rotation in the HBM residual, checked by mirror symmetry.

A blade turning at s Omega and its mirror image (reflected through a meridian plane: each
contact node's angle theta_j -> -theta_j and its tangential dof v_theta -> -v_theta, so
K -> P K P with P = diag(1, -1, 1) per node) turning at -s Omega are the same physical
problem seen in a mirror: the radial and axial responses are equal, the tangential ones
opposite. So the residual of (ROM, s = -1) at u must be P times the residual of
(mirrored ROM, s = +1) at P u, for both contact treatments, with friction. This catches a
sense applied to the casing but not to the friction (or the reverse), or applied twice.
"""
import dataclasses

import numpy as np
import pytest

from hbm.harmonic.residual import build_residual
from hbm.options import CasingOptions, ContactOptions, HbmOptions
from support import mirrored_rom, standin_rom


@pytest.mark.parametrize("method", ["dlft", "rl"])
def test_mirror_image_turning_the_other_way(method):
    rom = standin_rom(rotation=-1)
    mirrored, p = mirrored_rom(rom)
    opts = (CasingOptions(), ContactOptions(mu=0.3), HbmOptions(n_harmonics=5, n_time=64))
    res = build_residual(rom, *opts, method=method)
    res_m = build_residual(mirrored, *opts, method=method)
    om = 900.0
    u = 2.0 * np.random.default_rng(7).standard_normal(res.size)
    smp = res.samples(res.to_coefficients(u), om)
    assert 0.05 < smp.active.mean() < 0.95  # a mix of contact and flight
    pu = np.tile(p[:res.n_r], res.n_c)  # P on every harmonic block of the condensed unknowns
    R, J, dw = res(u, om)
    Rm, Jm, dwm = res_m(pu * u, om)
    # same operations on mirrored numbers: equal to round-off (1e-10 of the largest entry)
    np.testing.assert_allclose(R, pu * Rm, rtol=0, atol=1e-10 * abs(R).max())
    np.testing.assert_allclose(dw, pu * dwm, rtol=0, atol=1e-10 * abs(dw).max())
    np.testing.assert_allclose(np.asarray(J), pu[:, None] * np.asarray(Jm) * pu[None, :], rtol=0,
                               atol=1e-10 * abs(np.asarray(J)).max())
    # and the sense matters: the same ROM turning the other way gives another residual
    R_other = build_residual(dataclasses.replace(rom, rotation=1), *opts, method=method)(u, om, jacobian=False)
    assert abs(R_other - R).max() > 1e-2 * abs(R).max()


def test_friction_opposes_the_blade_speed():
    # no vibration velocity: the tip slides at s rho Omega e_theta, so the friction force
    # f_nl (internal-force convention, the force on the blade is -f_nl) is +mu lam s on theta
    for s in (1, -1):
        rom = standin_rom(rotation=s)
        res = build_residual(rom, CasingOptions(), ContactOptions(mu=0.2), HbmOptions(n_harmonics=3, n_time=32),
                             method="rl")  # penalty: lam > 0 wherever the tip is beyond the casing
        xr = np.zeros((res.n_c, res.n_r))
        xr[0, 0::3] = 1e-3  # a static radial displacement beyond the casing at every node
        smp = res.samples(xr, 1000.0)
        assert smp.lam.min() > 0
        np.testing.assert_allclose(smp.force[..., 1], 0.2 * s * smp.lam, rtol=1e-12)


def test_casing_seen_at_the_absolute_angle():
    # node j at the absolute angle s tau + theta_j meets eq. (28)'s casing there: written here
    # directly from eq. (28) (lobe centres at pi / n_l + k 2 pi / n_l)
    cas = CasingOptions(n_lobes=3, width=0.2)
    for s in (1, -1):
        rom = standin_rom(rotation=s)
        res = build_residual(rom, cas, ContactOptions(), HbmOptions(n_harmonics=3, n_time=32))
        a = s * res.basis.tau[:, None] + rom.theta[None, :]
        period = 2 * np.pi / cas.n_lobes
        phi = (a - np.pi / cas.n_lobes + period / 2) % period - period / 2  # angle from the nearest lobe centre
        d = cas.clearance - (cas.clearance + cas.penetration) * np.exp(-(phi / cas.width) ** 2)
        np.testing.assert_allclose(res.distance, d, rtol=0, atol=1e-15)
