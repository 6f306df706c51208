"""The validation march's contact fraction (hbm.ti.validation.OrbitValidation.contact_fraction)
is the share of time steps in contact, not the share of force samples with a force.

The force samples are block means of the per-step multipliers over a recording interval, so
a sample is > 0 as soon as one step of its block is in contact: a node that touches the
casing for a fifth of each block would read 100 % contact and "permanent contact". The
kernel counts the steps with a force per block (March.force_steps); these tests check that
count against a stride-1 march and the fraction against a quasi-static reference.
"""
import math

import numpy as np
import pytest

from hbm.options import CasingOptions
from hbm.ti.march import Marcher, Recording, modal_system, rom_modal_system
from hbm.ti.validation import march_from_hbm
from rom.model import modal_damping
from support import standin_rom


def test_force_steps_count_the_steps_with_a_multiplier():
    """Stand-in ROM, ovalised casing, friction; stride 7 from step 10 on three nodes (one twice):
    force_steps of sample i is the number of steps m = 7 + 7 i .. 13 + 7 i with lam_m > 0,
    read from a stride-1 march of every node (its sample k is lam at step k + 1)."""
    rng = np.random.default_rng(1)
    x0 = np.zeros(39)
    x0[0:27:3] = 3e-4
    x0[1:27:3] = 1e-5 * rng.standard_normal(9)
    v0 = 0.05 * rng.standard_normal(39)
    system, casing, n = rom_modal_system(standin_rom()), CasingOptions(), 600

    def run(rec):
        return Marcher(system, casing, 0.15, 1500.0, x0, v0, 2e-6, n, rec).advance(n).result()

    per_step = run(Recording(start=1, stride=1, n_samples=n, dofs=np.array([0]), force_nodes=np.arange(9)))
    assert np.array_equal(per_step.force_steps, (per_step.normal_force > 0).astype(float))
    nodes = np.array([0, 4, 8, 4])
    s, n0, ns = 7, 10, 84
    blocks = run(Recording(start=n0, stride=s, n_samples=ns, dofs=np.array([0]), force_nodes=nodes))
    lam = per_step.normal_force[:, nodes]
    first = n0 - s // 2  # first step of block 0
    want = np.array([(lam[first - 1 + i * s:first - 1 + (i + 1) * s] > 0).sum(axis=0) for i in range(ns)])
    assert np.array_equal(blocks.force_steps, want)
    # the case the count is for: blocks with a force in some of their steps only
    partial = (want > 0) & (want < s)
    assert partial.sum() >= 5 and want.sum() >= 20
    assert ((blocks.normal_force > 0) == (want > 0)).all()


# A two-node toy (compliance G, m/N, local (r, theta, z) of node 0 then node 1): its periods
# (< 0.1 ms) are far below a lobe's passage (3 ms at 50 rad/s), with 20 % damping: it follows
# the casing quasi-statically. The radial coupling is positive: a node pressed inwards pulls
# the other one inwards too, never into the casing.
G = 1e-8 * np.array([
    [4.0, 0.0, 0.0, 1.0, 0.0, 0.0],
    [0.0, 12.0, 0.0, 0.0, 0.0, 0.0],
    [0.0, 0.0, 5.0, 0.0, 0.0, 0.0],
    [1.0, 0.0, 0.0, 4.0, 0.0, 0.0],
    [0.0, 0.0, 0.0, 0.0, 12.0, 0.0],
    [0.0, 0.0, 0.0, 0.0, 0.0, 6.0],
])
OMEGA = 50.0  # rad/s
CASING = CasingOptions(n_lobes=8)  # a lobe every 2 pi / 8 rad


@pytest.mark.parametrize("n_time", [8, 64])
def test_a_node_touching_the_casing_in_every_sample_block_is_not_in_permanent_contact(n_time):
    """The toy from rest past 8 lobes, without friction, recorded on n_time samples per
    revolution: with 8 every force block spans one lobe period and holds one lobe passage of
    each node, so every force sample of both nodes is > 0.

    Reference: at rest on r = 0 and following the casing quasi-statically, node j is in
    contact where d_j(tau) < 0, i.e. |phi| < w sqrt(ln((c + p) / c)) around each lobe centre
    (eq. 28): a share 2 n_l w sqrt(ln((c + p) / c)) / (2 pi) = 0.1992 of the time for either
    node (their contact arcs, 1 rad apart, do not overlap modulo 2 pi / 8). Measured 0.1989
    with 8 and 64 samples; the samples with a force were 100 % and 37.5 %."""
    K = np.linalg.inv(G)
    M = 1e-3 * np.eye(6)
    C, _ = modal_damping(K, M, np.full(6, 0.2))
    system = modal_system(K, M, C, np.array([0.25, 0.25]), np.array([0.0, 1.0]))
    rest = np.zeros((3, 6))
    rest[1, 0] = rest[1, 3] = 1e-9  # a tiny orbit (m): the rest state with a scale to measure against
    ti = march_from_hbm(system, CASING, 0.0, rest, OMEGA, n_periods=4, dt=0.2 * 2.0 / system.omega.max(),
                        n_time=n_time)
    c, p, w = CASING.clearance, CASING.penetration, CASING.width
    share = 2 * CASING.n_lobes * w * math.sqrt(math.log((c + p) / c)) / (2 * math.pi)
    assert share == pytest.approx(0.1992, abs=1e-4)
    assert ti.max_penetration < 1e-12 and not ti.stays
    assert ti.contact_fraction == pytest.approx([share, share], abs=0.002)
    assert ti.locked_nodes.tolist() == []
    assert ti.outcome == "leaves" and ti.verdict() == "leaves"
