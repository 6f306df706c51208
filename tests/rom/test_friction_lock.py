"""Friction-lock check (rom.friction_lock) and the sense of rotation (rom.rotation), against
hand computations: a two-node compliance written down, its 2 x 2 minors solved by hand."""

import re

import numpy as np
import pytest

from rom.friction_lock import friction_lock
from rom.rotation import rotation_sign
from support import coarse_rom


def _toy(G: np.ndarray, eta: int = 2) -> np.ndarray:
    """A ROM stiffness whose boundary compliance is G: K = blockdiag(G^-1, modal stiffness)."""
    n = G.shape[0]
    K = np.zeros((n + eta, n + eta))
    K[:n, :n] = np.linalg.inv(G)
    K[n:, n:] = np.diag(np.linspace(1e9, 2e9, eta))
    return K


# Two nodes, local (r, theta, z) each; m/N. Node 0: radial-tangential coupling +3 (per unit
# G_rr = 10), node 1: -6 against G_rr = 4; cross terms small.
G2 = 1e-8 * np.array([
    [10.0, 3.0, 0.5, 1.0, 0.2, 0.0],
    [3.0, 8.0, 0.0, 0.4, 0.3, 0.0],
    [0.5, 0.0, 5.0, 0.0, 0.0, 0.1],
    [1.0, 0.4, 0.0, 4.0, -6.0, 0.2],
    [0.2, 0.3, 0.0, -6.0, 12.0, 0.0],
    [0.0, 0.0, 0.1, 0.2, 0.0, 6.0],
])


@pytest.mark.parametrize("s", [1, -1])
def test_two_nodes_by_hand(s):
    assert np.linalg.eigvalsh(G2).min() > 0  # a compliance: SPD
    lock = friction_lock(_toy(G2), 2, s)
    np.testing.assert_allclose(lock.compliance_rr, 1e-8 * np.array([[10.0, 1.0], [1.0, 4.0]]), rtol=1e-12)
    np.testing.assert_allclose(lock.compliance_rtheta, 1e-8 * np.array([[3.0, 0.2], [0.4, -6.0]]), rtol=1e-12)
    # one node: r_j = -lam (G_rr + s mu G_rt): node 0 locks above 10/3 for s = -1, node 1
    # above 4/6 for s = +1; the other never
    expected = {1: [np.inf, 4.0 / 6.0], -1: [10.0 / 3.0, np.inf]}[s]
    np.testing.assert_allclose(lock.mu_node, expected, rtol=1e-12)
    assert lock.dragged_in(0.7).tolist() == {1: [False, True], -1: [False, False]}[s]
    # the pair: det(A) = (10 + 3 s mu)(4 - 6 s mu) - (1 + 0.2 s mu)(1 + 0.4 s mu)
    #               = 39 - 48.6 s mu - 18.08 mu^2 (times 1e-16)
    roots = np.roots([-18.08, -48.6 * s, 39.0])
    pair = roots[(roots.imag == 0) & (roots.real > 0)].real.min()
    mu_set = min(pair, min(expected))
    assert lock.mu_set == pytest.approx(mu_set, rel=1e-10)
    assert (lock.mu_set < min(expected)) == bool(lock.set_nodes.sum() == 2)
    # below mu_set every principal minor is positive, above one is not (the P-matrix test)
    for mu, p_matrix in ((0.99 * lock.mu_set, True), (1.01 * lock.mu_set, False)):
        A = lock.radial_compliance(mu)
        minors = [A[0, 0], A[1, 1], np.linalg.det(A)]
        assert (min(minors) > 0) == p_matrix


def test_warning_names_the_dragged_node():
    lock = friction_lock(_toy(G2), 2, 1)
    assert lock.warnings(0.1) == []
    (w,) = lock.warnings(0.8)
    assert "node(s) 1 into the casing" in w
    assert any("INTO the casing" in line for line in lock.report(0.8))


def test_rotor67_contact_set_threshold_by_brute_force():
    # mu_set from the eigenvalues of B^-1 C against a direct scan of the 511 principal minors
    # of A(mu) on the coarse rotor 67 ROM: just below it all are positive, just above one is not.
    rom = coarse_rom()
    import itertools

    for s in (1, -1):
        lock = friction_lock(rom.K, rom.n_boundary, s)

        def all_minors_positive(mu):
            A = lock.radial_compliance(mu) / abs(lock.compliance_rr).max()
            return all(np.linalg.det(A[np.ix_(i, i)]) > 0 for k in range(1, 10)
                       for i in map(list, itertools.combinations(range(9), k)))

        assert 0 < lock.mu_set <= lock.mu_node.min()
        assert all_minors_positive(lock.mu_set * (1 - 1e-6)) and not all_minors_positive(lock.mu_set * (1 + 1e-6))


def test_rotation_sign():
    rom = coarse_rom()
    # rotor 67's table: theta_TE - theta_LE = +0.33 rad, so the LE leads turning towards -theta
    assert rom.theta[-1] - rom.theta[0] == pytest.approx(0.334, abs=0.01)
    assert rotation_sign("le-leads", rom.theta) == -1
    assert rotation_sign("le-leads", -rom.theta) == 1
    assert (rotation_sign("+", rom.theta), rotation_sign("-", rom.theta)) == (1, -1)
    with pytest.raises(ValueError, match="span an angle"):
        rotation_sign("le-leads", np.zeros(9))
    with pytest.raises(ValueError, match="unknown rotation"):
        rotation_sign("cw", rom.theta)


@pytest.mark.parametrize("bad", [0, 2, "+"])
def test_every_stage_refuses_a_sense_that_is_not_a_sign(bad):
    """The ROM, its friction-lock table, the HBM residual and the time integration's system
    each refuse a rotation other than +1 / -1 and name the value (one check per package)."""
    from dataclasses import replace

    from hbm.harmonic.residual import build_residual
    from hbm.options import CasingOptions, ContactOptions, HbmOptions
    from hbm.ti.march import rom_modal_system

    rom = coarse_rom()
    message = re.escape("rotation must be +1 or -1") + ".*got " + re.escape(repr(bad))
    with pytest.raises(ValueError, match=message):
        replace(rom, rotation=bad)
    with pytest.raises(ValueError, match=message):
        friction_lock(rom.K, rom.n_boundary, bad)
    ok = rom_modal_system(rom)
    with pytest.raises(ValueError, match=message):
        replace(ok, rotation=bad)
    unchecked = replace(rom)
    object.__setattr__(unchecked, "rotation", bad)  # a ROM object from elsewhere, past its own check
    with pytest.raises(ValueError, match=message):
        build_residual(unchecked, CasingOptions(), ContactOptions(), HbmOptions(n_harmonics=2, n_time=16), method="rl")
