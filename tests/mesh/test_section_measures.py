"""Section.meridional_arc / Section.area and mesh.blade.reference_volume in closed form.

A section on a 45-degree conical streamsurface, r = r0 + z, z in [0, L]: the meridional arc
is sqrt(2) z, so a constant thickness t0 gives the area sqrt(2) L t0 (the axial length L
alone would give 1/sqrt(2) of it), and a thickness t0 sin(pi z / L) gives
int t0 sin(pi s / (sqrt 2 L)) ds = 2 sqrt(2) L t0 / pi. reference_volume integrates the
areas over the sections' mean radii with trapezoids: for two sections, the mean of their
areas times the difference of their mean radii.
"""
import numpy as np
import pytest

from mesh.blade import reference_volume
from mesh.geometry import Section

L, T0, R0 = 0.05, 0.002, 0.2


def _section(number, r0, thickness):
    z = np.linspace(0.0, L, 2001)
    return Section(number=number, z=z, r=r0 + z, rtheta_upper=0.5 * thickness(z), thickness=thickness(z))


def test_meridional_arc_and_area_on_a_cone():
    s = _section(1, R0, lambda z: np.full_like(z, T0))
    np.testing.assert_allclose(s.meridional_arc(), np.sqrt(2) * s.z, rtol=1e-12, atol=1e-15)
    assert s.area() == pytest.approx(np.sqrt(2) * L * T0, rel=1e-12)
    bump = _section(1, R0, lambda z: T0 * np.sin(np.pi * z / L))
    assert bump.area() == pytest.approx(2 * np.sqrt(2) * L * T0 / np.pi, rel=1e-6)  # trapezoids, 2000 steps


def test_reference_volume_of_two_sections():
    low = _section(1, R0, lambda z: np.full_like(z, T0))
    high = _section(2, R0 + 0.1, lambda z: np.full_like(z, 2 * T0))
    a1, a2 = np.sqrt(2) * L * T0, 2 * np.sqrt(2) * L * T0
    assert reference_volume((low, high)) == pytest.approx(0.5 * (a1 + a2) * 0.1, rel=1e-12)
