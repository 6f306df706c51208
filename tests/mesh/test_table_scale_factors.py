"""The rotor 67 table's per-block scale factors and the tables' blade counts.

Rotor 67's format (the file's own header): every block is "a scale factor followed by JM
numbers", the values being factor x number. The shipped table has factors 1.0 throughout
("always 1.0"), so a reader that ignored them would read it right and any other table
wrong: here a copy with the axial and the radius factors changed, read against the printed
numbers times the factors. Blade counts: NASA rotor 67 has 22 blades (the table's NB),
rotor 37 has 36 (NASA TP-1659; its table does not say, shared/data/README.md).
"""
import pytest

from support import SHARED
from mesh.geometry import read_geometry

R67 = SHARED / "data" / "rotor67" / "rotor67geometry.dat"
R37 = SHARED / "data" / "rotor37" / "rotor37geometry.dat"
FT = 0.3048


def _with_factors(tmp_path, factors):
    """A copy of the rotor 67 table with the scale factor of the named blocks replaced."""
    lines = R67.read_text().splitlines()
    first = next(i for i, l in enumerate(lines) if l.strip().startswith("Surface number"))
    out = list(lines)
    for i in range(first, len(lines) - 1):
        for title, factor in factors.items():
            if lines[i].strip() == title:
                assert lines[i + 1].strip() == "1.000000"  # the factor line, as shipped
                out[i + 1] = f"  {factor:.6f}"
    p = tmp_path / "r67_factors.dat"
    p.write_text("\n".join(out) + "\n")
    return p


def test_block_scale_factors_multiply_the_values(tmp_path):
    g = read_geometry(_with_factors(tmp_path, {"Axial Distance": 0.5, "Radius": 2.0}), "rotor67", "ft")
    hub = g.section(1)
    # Surface 1, J = 16 (the LE), as printed: axial -0.002474 ft, radius 0.313693 ft
    assert hub.z[0] == pytest.approx(0.5 * -0.002474 * FT, abs=1e-12)
    assert hub.r[0] == pytest.approx(2.0 * 0.313693 * FT, abs=1e-12)
    # the unscaled blocks are untouched: r*theta 0.002090 ft, thickness at J = 17 0.000646 ft
    assert hub.rtheta_upper[0] == pytest.approx(0.002090 * FT, abs=1e-12)
    assert hub.thickness[1] == pytest.approx(0.000646 * FT, abs=1e-12)
    # the full meridional lines (hub/casing) carry the factors too: J = 1 axial -0.830950 ft
    assert g.meridional_z[0, 0] == pytest.approx(0.5 * -0.830950 * FT, abs=1e-12)


def test_blade_counts_of_the_two_rotors():
    assert read_geometry(R67, "rotor67").n_blades == 22
    assert read_geometry(R37, "rotor37").n_blades == 36
