"""What the march records (hbm.ti.march.Recording) on the stand-in ROM with the ovalised
casing and friction: block-mean contact forces against the per-step multipliers of the same
march, and a march advanced in uneven chunks against one advanced in one call.

Block means must keep the impulse of the multipliers they average, and a march advanced in
chunks (the sweep's early stop) must not depend on where the chunks end.
"""
import numpy as np
import pytest

from hbm.options import CasingOptions
from hbm.ti.march import Marcher, Recording, critical_time_step, massless_system, rom_modal_system
from support import standin_rom

OMEGA, DT, N = 1500.0, 2e-6, 600
MU = 0.15


def start_state():
    """An initial state that hits the lobes within a few hundred steps, several nodes at once."""
    rng = np.random.default_rng(1)
    x0 = np.zeros(39)
    x0[0:27:3] = 3e-4
    x0[1:27:3] = 1e-5 * rng.standard_normal(9)
    return x0, 0.05 * rng.standard_normal(39)


def marcher(rec):
    x0, v0 = start_state()
    return Marcher(rom_modal_system(standin_rom()), CasingOptions(), MU, OMEGA, x0, v0, DT, N, rec)


def test_block_mean_forces_equal_the_mean_of_the_per_step_multipliers():
    """Stride 7 from step 10 on three of the nine nodes, one of them twice (the others not
    recorded): sample i is the mean of lam_m over m = 7 + 7 i .. 13 + 7 i, read from a
    stride-1 march of every node (its sample k is lam at step k + 1)."""
    every = Recording(start=1, stride=1, n_samples=N, dofs=np.array([0]), force_nodes=np.arange(9))
    per_step = marcher(every).advance(N).result()
    assert per_step.contact_steps > 20 and (per_step.normal_force > 0).sum(axis=1).max() >= 2
    nodes = np.array([0, 4, 8, 4])
    s, n0, ns = 7, 10, 84
    rec = Recording(start=n0, stride=s, n_samples=ns, dofs=np.array([0]), force_nodes=nodes)
    blocks = marcher(rec).advance(N).result()
    lam = per_step.normal_force[:, nodes]  # lam at step k + 1
    fr = per_step.friction_force[:, nodes]
    first = n0 - s // 2  # first step of block 0
    want = np.array([lam[first - 1 + i * s:first - 1 + (i + 1) * s].mean(axis=0) for i in range(ns)])
    want_fr = np.array([fr[first - 1 + i * s:first - 1 + (i + 1) * s].mean(axis=0) for i in range(ns)])
    assert np.abs(want).max() > 0.0 and np.abs(want_fr).max() > 0.0
    assert np.allclose(blocks.normal_force, want, rtol=1e-12, atol=1e-12 * np.abs(want).max())
    assert np.allclose(blocks.friction_force, want_fr, rtol=1e-12, atol=1e-12 * np.abs(want_fr).max())


def test_a_march_in_uneven_chunks_records_exactly_what_one_call_records():
    """Chunk ends inside force blocks, extreme blocks and between sections: bit for bit."""
    rec = Recording(start=5, stride=9, n_samples=60, dofs=np.array([0, 24]), force_nodes=np.arange(9),
                    section_stride=4, extreme_stride=50)
    one = marcher(rec).advance(N).result()
    m = marcher(rec)
    for chunk in (1, 6, 50, 123, 7, 1, 200, 1000):
        m.advance(chunk)
    chunked = m.result()
    assert one.contact_steps > 20 and chunked.n_steps == one.n_steps == N
    for name in ("displacement", "normal_force", "friction_force", "sections", "extremes", "x_final"):
        assert np.array_equal(getattr(chunked, name), getattr(one, name)), name


#: every step's sample, so that a split anywhere is compared on what follows it
EVERY_STEP = Recording(start=1, stride=1, n_samples=N, dofs=np.array([0, 24]), force_nodes=np.arange(9),
                       section_stride=4, extreme_stride=50)


def _assert_every_split_is_one_march(make, one, splits):
    """A march from make() advanced to each split, then to N, records what `one` (the march in
    one call) records, bit for bit."""
    for split in splits[splits < N]:
        m = make()
        m.advance(int(split))
        chunked = m.advance(N - int(split)).result()
        for name in ("displacement", "normal_force", "friction_force", "sections", "extremes", "x_final"):
            assert np.array_equal(getattr(chunked, name), getattr(one, name)), (int(split), name)


def test_a_massless_march_split_at_any_contact_step_is_one_march():
    """The massless scheme carries the forces of a contact step into the next step: a call
    that ends on one must hand them over whole (their compliance columns included, or the next
    step's prediction misses their correction and its forces come out wrong; a split at
    almost any contact step then moved the forces by ~100 N). Every contact step of the march
    is tried as the split, bit for bit."""
    full = rom_modal_system(standin_rom())
    system = massless_system(full, cutoff=np.sort(full.omega)[len(full.omega) // 2])
    dt = min(DT, 0.5 * critical_time_step(system, MU))
    x0, v0 = start_state()

    def make():
        return Marcher(system, CasingOptions(), MU, OMEGA, x0, v0, dt, N, EVERY_STEP)

    one = make().advance(N).result()
    contact = np.nonzero((one.normal_force > 0).any(axis=1))[0] + 1  # massless: sample k is lam at step k + 1
    assert len(contact) > 50
    _assert_every_split_is_one_march(make, one, contact)


@pytest.mark.parametrize("exponential", [False, True], ids=["carpenter", "exponential"])
def test_a_march_with_friction_split_at_any_contact_step_is_one_march(exponential):
    """A contact step's sliding directions and active set start the next step (its first
    guess): a call that ends on one must hand them over, or the next call's first step starts
    from the prediction's direction and the march moves off (at 1e-6 s on rotor 67 a sweep's
    chunked march then left the one-call march within a few revolutions, with hundreds of
    steps whose direction did not settle). Every contact step followed by another is tried as
    the split, bit for bit."""
    x0, v0 = start_state()

    def make():
        return Marcher(rom_modal_system(standin_rom()), CasingOptions(), MU, OMEGA, x0, v0, DT, N, EVERY_STEP,
                       exponential=exponential)

    one = make().advance(N).result()
    in_contact = (one.normal_force > 0).any(axis=1)  # sample k: step k + 1 (Carpenter: lam_{k+1} acts at k + 2)
    splits = np.nonzero(in_contact[:-1] & in_contact[1:])[0] + 1
    assert len(splits) > 30 and np.abs(one.friction_force).max() > 0.0
    _assert_every_split_is_one_march(make, one, splits)


@pytest.mark.parametrize("field, value, message", [
    ("force_nodes", [9], r"force node \[9\] outside the 9 contact nodes 0 .. 8"),
    ("force_nodes", [0, -1], r"force node \[-1\] outside"),
    ("dofs", [39], r"dof \[39\] outside the 39 dof 0 .. 38"),
    ("dofs", [-2], r"dof \[-2\] outside"),
])
def test_a_recording_of_a_node_or_dof_the_model_lacks_is_refused(field, value, message):
    """Refused by name, not read past the kernel's tables (a node past the last recorded 0 N,
    or wrote beyond them) nor wrapped round to the last ones."""
    kwargs = dict(start=1, stride=1, n_samples=10, dofs=np.array([0]), force_nodes=np.arange(9))
    kwargs[field] = np.array(value)
    with pytest.raises(ValueError, match=message):
        marcher(Recording(**kwargs))
