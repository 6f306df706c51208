"""The table readers: values and units against the printed file, and clear errors on bad tables."""
from pathlib import Path

import numpy as np
import pytest

from support import SHARED
from mesh.blade import reference_volume
from mesh.geometry import GeometryError, read_geometry

R67 = SHARED / "data" / "rotor67" / "rotor67geometry.dat"
R37 = SHARED / "data" / "rotor37" / "rotor37geometry.dat"
FT = 0.3048


@pytest.fixture(scope="module")
def r67():
    return read_geometry(R67, "rotor67", "ft")


def test_rotor67_values_against_the_printed_table(r67):
    assert len(r67.sections) == 14 and r67.n_blades == 22
    hub = r67.section(1)
    assert hub.z.shape == (70,)  # JLE = 16 .. JTE = 85
    # Surface 1, point J = 16 (the LE), as printed: axial -0.002474, r*theta 0.002090, radius 0.313693 ft.
    assert hub.z[0] == pytest.approx(-0.002474 * FT, abs=1e-12)
    assert hub.rtheta_upper[0] == pytest.approx(0.002090 * FT, abs=1e-12)
    assert hub.r[0] == pytest.approx(0.313693 * FT, abs=1e-12)
    # J = 17: thickness 0.000646 ft; the lower surface is upper minus thickness.
    assert hub.thickness[1] == pytest.approx(0.000646 * FT, abs=1e-12)
    assert hub.theta_lower[1] == pytest.approx((0.002413 - 0.000646) / 0.313701, rel=1e-9)
    # LE and TE are closed (zero thickness) on every section.
    assert all(s.thickness[0] == 0 and s.thickness[-1] == 0 for s in r67.sections)


def test_units_scale_linearly(r67, tmp_path):
    """The table without its statement of the unit (which refuses any other), read in inches."""
    table = tmp_path / "r67.dat"
    table.write_text("\n".join(line for line in R67.read_text().splitlines() if "ARE IN FEET" not in line))
    inches = read_geometry(table, "rotor67", "in")
    np.testing.assert_allclose(inches.section(13).r * FT / 0.0254, r67.section(13).r, rtol=1e-12)


def test_reference_volume_matches_the_documented_value(r67):
    # shared/data/README.md: about 4.8e-5 m^3 for sections 1..13 ("about": 2 % slack).
    v = reference_volume(r67.sections[:13])
    assert v == pytest.approx(4.8e-5, rel=0.02)


def test_rotor37_reads_in_metres_and_radians():
    g = read_geometry(R37, "rotor37", "cm")
    assert len(g.sections) == 13
    tip = g.section(13)
    # Table IV, surface 13, J = 100: Z 3.4154623 cm, R 24.4678631 cm, closed TE.
    assert tip.z[-1] == pytest.approx(0.034154623, abs=1e-12)
    assert tip.r[-1] == pytest.approx(0.244678631, abs=1e-12)
    assert tip.thickness[-1] == pytest.approx(0.0, abs=1e-12)
    assert np.all(np.array([s.thickness.max() for s in g.sections]) > 0)


# --- corrupted copies -------------------------------------------------------------------

def _lines():
    return R67.read_text().splitlines()


def _write(tmp_path, lines) -> Path:
    p = tmp_path / "bad.dat"
    p.write_text("\n".join(lines) + "\n")
    return p


def _block_start(lines, surface, title):
    s = next(i for i, l in enumerate(lines) if l.strip().startswith(f"Surface number {surface:2d}"))
    return next(i for i in range(s, len(lines)) if title in lines[i])


def test_truncated_block_is_named(tmp_path):
    lines = _lines()
    i = _block_start(lines, 5, "Axial Distance")
    del lines[i + 5]  # drop 8 of the 110 axial values of surface 5
    with pytest.raises(GeometryError, match=r"surface 5, block 'Axial Distance' truncated"):
        read_geometry(_write(tmp_path, lines))


def test_missing_surface_is_named(tmp_path):
    lines = _lines()
    s = next(i for i, l in enumerate(lines) if l.strip().startswith("Surface number 14"))
    with pytest.raises(GeometryError, match=r"surface\(s\) 14 missing"):
        read_geometry(_write(tmp_path, lines[:s]))


def test_negative_thickness_inside_the_blade_is_named(tmp_path):
    lines = _lines()
    i = _block_start(lines, 7, "Tangential thickness")
    # Values J = 25..32 are on the 4th data line after the scale factor; make J = 25 negative.
    row = lines[i + 5].split()
    row[0] = "-0.001000"
    lines[i + 5] = "".join(f"{v:>10s}" for v in row)
    with pytest.raises(GeometryError, match=r"surface 7.*negative thickness.*J=25"):
        read_geometry(_write(tmp_path, lines))


def test_unknown_units_and_format(tmp_path):
    with pytest.raises(GeometryError, match="unknown length unit 'furlong'"):
        read_geometry(R67, "rotor67", "furlong")
    with pytest.raises(GeometryError, match="unknown geometry format"):
        read_geometry(R67, "rotor99", "ft")


def test_garbage_in_a_block_is_named(tmp_path):
    lines = _lines()
    i = _block_start(lines, 3, "Radius*Theta")
    lines[i + 3] = lines[i + 3][:20] + " abc" + lines[i + 3][24:]
    with pytest.raises(GeometryError, match=r"non-numeric data in surface 3, block 'Radius\*Theta Distance'"):
        read_geometry(_write(tmp_path, lines))


def test_missing_file():
    with pytest.raises(GeometryError, match="not found"):
        read_geometry(Path("/nonexistent/rotor.dat"))
