"""The casing profile the march tabulates (hbm.ti.march.casing_profile) against the casing law.

Where a casing period is a whole number P of steps (the sweep's steps are chosen so), the
kernel reads d_j at step m from row m mod P of a table instead of evaluating eq. (28) at
every step and node. The table must be the law at the kernel's own instants (tau = Omega m
dt, up to 200 revolutions), and a march on it must be the march on the law up to round-off:
a row read one step off moves the casing by Omega dt / w = 1e-3 lobe widths, which shows
as 2e-5 to 7e-5 of the displacement range within one revolution on the coarse ROM.
"""
import math

import numpy as np
import pytest

from hbm.contact.casing import casing_distance
from hbm.options import CasingOptions, ContactOptions
from hbm.ti import march as ti_march
from hbm.ti.march import Marcher, Recording, casing_profile, rom_modal_system
from hbm.ti.settle import SUBSECTIONS
from hbm.ti.sweep import steps_per_revolution
from support import coarse_rom, standin_rom

CASING = CasingOptions()


def sweep_dt(omega: float) -> tuple[int, float]:
    """(steps per revolution, dt) of the sweep at omega (rad/s) with the default options."""
    n_rev = steps_per_revolution(omega, 1e-7, math.lcm(CASING.n_lobes * SUBSECTIONS, 256))
    return n_rev, 2.0 * math.pi / (omega * n_rev)


@pytest.mark.parametrize("omega", [400.0, 1437.5, 2000.0])
def test_the_profile_is_the_casing_law_at_every_step_of_200_revolutions(omega):
    n_rev, dt = sweep_dt(omega)
    theta = np.linspace(-0.02, 0.03, 9)
    table = casing_profile(CASING, theta, omega, dt)
    assert table.shape == (n_rev // CASING.n_lobes, 9)
    steps = np.random.default_rng(0).integers(0, 200 * n_rev, 2000)
    steps[:3] = (0, table.shape[0] - 1, table.shape[0])  # the first row, the last and the wrap
    law = casing_distance(omega * (steps * dt), theta, CASING)  # as the kernel's tau = Omega (m dt)
    scale = CASING.clearance + CASING.penetration
    # the law's own floor at tau ~ 1257 rad rounds z to ~1e-12: d to ~1e-15 m
    assert np.abs(table[steps % table.shape[0]] - law).max() < 1e-10 * scale
    assert np.ptp(law) > 0.9 * scale  # the steps sample the lobes, not only the gaps between them


def test_no_profile_where_a_casing_period_is_not_whole_steps():
    theta = np.zeros(9)
    _, dt = sweep_dt(1000.0)
    assert casing_profile(CASING, theta, 1000.0, dt).shape[0] > 0
    assert casing_profile(CASING, theta, 1000.0, 1.0001 * dt).shape == (0, 9)  # not whole steps
    # whole to round-off only: 1e-12 off would shift the table's phase every casing period
    assert casing_profile(CASING, theta, 1000.0, (1.0 + 1e-12) * dt).shape == (0, 9)
    assert casing_profile(CASING, theta, 1000.0, (1.0 + 4e-16) * dt).shape[0] > 0
    assert casing_profile(CASING, theta, 0.0, dt).shape == (0, 9)  # a casing at rest
    assert casing_profile(CASING, theta, 1e-3, dt).shape == (0, 9)  # far too long a period to keep


@pytest.mark.parametrize("omega", [650.0, 1400.0])
def test_a_march_on_the_profile_is_the_march_on_the_law(omega, monkeypatch):
    """One revolution from rest on the coarse ROM, contact in over a fifth of the steps."""
    system = rom_modal_system(coarse_rom())
    n_rev, dt = sweep_dt(omega)
    nb = system.n_boundary
    rec = Recording(start=n_rev // 256, stride=n_rev // 256, n_samples=255, dofs=np.arange(0, 3 * nb, 3),
                    force_nodes=np.arange(nb))
    zero = np.zeros(system.n_dof)

    def one_revolution():
        m = Marcher(system, CASING, ContactOptions().mu, omega, zero, zero, dt, n_rev, rec)
        return m._profile.shape[0], m.advance(n_rev).result()

    rows, table = one_revolution()
    monkeypatch.setattr(ti_march, "PROFILE_MAX_ENTRIES", 0)
    no_rows, law = one_revolution()
    assert rows == n_rev // CASING.n_lobes and no_rows == 0
    assert table.contact_steps == law.contact_steps > 0.2 * n_rev
    span = np.ptp(law.displacement, axis=0).max()
    assert np.abs(table.displacement - law.displacement).max() < 1e-10 * span
    assert np.abs(table.normal_force - law.normal_force).max() < 1e-8 * np.abs(law.normal_force).max()


def test_a_march_on_the_profile_in_uneven_chunks_is_one_march():
    """The stand-in ROM with a casing period of 1000 steps: chunks that end on and across the
    table's wrap give, bit for bit, what one call gives."""
    omega, n = 1500.0, 3000
    dt = 2.0 * math.pi / (CASING.n_lobes * omega * 1000)
    rng = np.random.default_rng(1)
    x0 = np.zeros(39)
    x0[0:27:3] = 3e-4
    v0 = 0.05 * rng.standard_normal(39)
    rec = Recording(start=5, stride=9, n_samples=300, dofs=np.array([0, 24]), force_nodes=np.arange(9),
                    section_stride=4, extreme_stride=50)

    def marcher():
        return Marcher(rom_modal_system(standin_rom()), CASING, 0.15, omega, x0, v0, dt, n, rec)

    one = marcher()
    assert one._profile.shape[0] == 1000
    one = one.advance(n).result()
    m = marcher()
    for chunk in (999, 1, 1000, 7, 500, 493, 1000):
        m.advance(chunk)
    chunked = m.result()
    assert one.contact_steps > 100 and chunked.n_steps == one.n_steps == n
    for name in ("displacement", "normal_force", "friction_force", "sections", "extremes", "x_final"):
        assert np.array_equal(getattr(chunked, name), getattr(one, name)), name
