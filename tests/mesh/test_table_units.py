"""The length unit a NASA table states in its text: taken when the scene gives none, a
contradicting scene unit refused, a table stating none refused without one."""
from pathlib import Path

import numpy as np
import pytest

from mesh.geometry import GeometryError, read_geometry
from mesh.options import BladeOptions
from support import SHARED

R67 = SHARED / "data" / "rotor67" / "rotor67geometry.dat"
R37 = SHARED / "data" / "rotor37" / "rotor37geometry.dat"


def _write(tmp_path: Path, lines, name="table.dat") -> Path:
    p = tmp_path / name
    p.write_text("\n".join(lines) + "\n")
    return p


def test_rotor37_without_units_is_read_in_its_centimetres():
    stated = read_geometry(R37, "rotor37")
    cm = read_geometry(R37, "rotor37", "cm")
    # Table IV, surface 13, J = 100: R 24.4678631 cm; the tip radius about 0.25 m, not 7.5 m (feet)
    assert stated.section(13).r[-1] == pytest.approx(0.244678631, abs=1e-12)
    assert stated.section(13).r.max() == pytest.approx(0.2523, abs=1e-4)
    for a, b in zip(stated.sections, cm.sections):
        np.testing.assert_array_equal(a.r, b.r)
        np.testing.assert_array_equal(a.z, b.z)
    assert (stated.units, stated.stated.unit, stated.stated.line) == ("cm", "cm", 2)
    assert stated.stated.text == "Z and R are in centimeters"


def test_rotor67_without_units_is_read_in_its_feet():
    stated = read_geometry(R67, "rotor67")
    ft = read_geometry(R67, "rotor67", "ft")
    assert stated.section(13).r.max() == ft.section(13).r.max()
    assert stated.section(13).r.max() == pytest.approx(0.2432, abs=1e-4)  # the blade tip section, m
    np.testing.assert_array_equal(stated.meridional_z, ft.meridional_z)
    # "THE DIMENSIONS ARE IN FEET." on line 50, not the "0.024 inches" of the clearance (line 14)
    assert (stated.units, stated.stated.unit, stated.stated.line) == ("ft", "ft", 50)


def test_rotor37_read_in_feet_is_refused_naming_both_units():
    with pytest.raises(GeometryError) as err:
        read_geometry(R37, "rotor37", "ft")
    text = str(err.value)
    assert f"{R37}:2:" in text and "centimeters" in text and 'units = "cm"' in text
    assert '[blade] units = "ft"' in text


def test_rotor67_read_in_inches_is_refused():
    with pytest.raises(GeometryError, match=r'rotor67geometry\.dat:50: .*FEET.*units = "in"'):
        read_geometry(R67, "rotor67", "in")


def test_a_quantity_in_inches_is_not_the_tables_unit(tmp_path):
    lines = R67.read_text().splitlines()
    assert "0.024 inches" in lines[13] and "0.040 inches" in lines[19]
    assert lines[49].strip() == "THE DIMENSIONS ARE IN FEET."
    del lines[49]  # rotor 67 without its statement: the clearance's inches remain
    p = _write(tmp_path, lines)
    with pytest.raises(GeometryError, match=r"does not state its length unit.*\[blade\] units.*ft, in, cm, mm, m"):
        read_geometry(p, "rotor67")
    assert read_geometry(p, "rotor67", "in").section(13).r.max() == pytest.approx(
        read_geometry(R67, "rotor67").section(13).r.max() / 12, rel=1e-12)


def test_table_stating_no_unit_needs_one(tmp_path):
    lines = R37.read_text().splitlines()
    p = _write(tmp_path, [lines[0]] + lines[2:])  # Table IV without "Z and R are in centimeters"
    with pytest.raises(GeometryError) as err:
        read_geometry(p, "rotor37")
    assert str(p) in str(err.value) and "set [blade] units" in str(err.value)
    assert read_geometry(p, "rotor37", "mm").section(13).r[-1] == pytest.approx(0.0244678631, abs=1e-12)


@pytest.mark.parametrize("statement, unit", [
    (" Rotor 37 blade geometry (centimetres)", "cm"),
    (" All coordinates are given in millimeters.", "mm"),
    (" Dimensions in metres", "m"),
    (" X, Y and Z are in inches", "in"),
])
def test_other_wordings_of_the_unit(tmp_path, statement, unit):
    lines = R37.read_text().splitlines()
    g = read_geometry(_write(tmp_path, [statement] + lines[2:]), "rotor37")
    assert g.units == unit and g.stated.line == 1
    assert g.section(13).r[-1] == pytest.approx(24.4678631 * {"cm": 0.01, "mm": 0.001, "m": 1.0, "in": 0.0254}[unit])


def test_a_table_contradicting_itself_is_refused(tmp_path):
    lines = R37.read_text().splitlines()
    p = _write(tmp_path, lines[:2] + [" (feet)"] + lines[2:])
    with pytest.raises(GeometryError, match=r"two length units: centimeters on line 2 .* feet on line 3"):
        read_geometry(p, "rotor37", "cm")


def test_data_after_the_header_is_not_searched(tmp_path):
    # a unit word inside a surface block is not the header's: the block's own error is raised
    lines = R37.read_text().splitlines()
    i = next(k for k, l in enumerate(lines) if l.strip().startswith("SURFACE NUMBER     2"))
    lines.insert(i + 1, " Z and R are in feet")
    with pytest.raises(GeometryError, match=r"non-numeric data in surface 2"):
        read_geometry(_write(tmp_path, lines), "rotor37")


def test_blade_options_keep_a_tables_units_unset():
    assert BladeOptions().units is None
    assert BladeOptions(format="rotor37", units="cm").units == "cm"
    with pytest.raises(ValueError, match="units is required with mesh"):
        BladeOptions(mesh="blade.inp")
