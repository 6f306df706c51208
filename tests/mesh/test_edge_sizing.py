"""The LE/TE size field (mesh.blade.edge_thickness, edge_sizing) on synthetic sections whose
edge thickness is known in closed form.

The section: r = 1 m (so the meridional arc is z), z in [0, L], a tangential thickness that
rises at slope 3 from both edges to a plateau T, t = min(3 z, 3 (L - z), T), and a straight
camber of slope c in the unrolled streamsurface (r theta_upper = c z + t / 2). Normal
thickness t / sqrt(1 + c^2), distance along the camber d = z sqrt(1 + c^2): the thickness
"one thickness behind the edge" solves t_n(d) = d; on the plateau that is
T / sqrt(1 + c^2) (c = 0.75: 0.8 T; the rise ends at z = T / 3, before the crossing).
edge_sizing: size on the edge lines = that thickness / edge_layers, capped at
element_size; ramp = (element_size - edge size) / size_growth.
"""
import numpy as np
import pytest

from mesh.blade import edge_sizing, edge_thickness
from mesh.geometry import Section
from mesh.options import MeshOptions

L, T = 0.1, 0.01


def _section(c):
    z = np.linspace(0.0, L, 101)
    t = np.minimum(np.minimum(3 * z, 3 * (L - z)), T)
    return Section(number=1, z=z, r=np.ones_like(z), rtheta_upper=c * z + 0.5 * t, thickness=t)


@pytest.mark.parametrize("c", (0.0, 0.75))
def test_edge_thickness_in_closed_form(c):
    assert edge_thickness(_section(c)) == pytest.approx(T / np.sqrt(1 + c * c), rel=1e-9)


@pytest.mark.parametrize("layers", (1, 2, 4))
def test_edge_size_is_the_edge_thickness_over_the_layers(layers):
    s = edge_sizing((_section(0.75),), MeshOptions(element_size=0.05, edge_layers=layers, size_growth=0.5))
    assert s.edge_thickness == pytest.approx(0.008, rel=1e-9)
    assert s.edge_size == pytest.approx(0.008 / layers, rel=1e-9)
    assert s.bulk_size == 0.05
    assert s.ramp == pytest.approx((0.05 - 0.008 / layers) / 0.5, rel=1e-9)


def test_edge_size_is_capped_at_the_element_size():
    s = edge_sizing((_section(0.0), _section(0.75)), MeshOptions(element_size=0.005, edge_layers=1))
    assert s.edge_thickness == pytest.approx(0.008, rel=1e-9)  # the thinner section's
    assert s.edge_size == 0.005 and s.ramp == 0.0
