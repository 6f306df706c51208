"""Every check of the two table readers (mesh.geometry) on a corrupted copy of the shipped
NASA table: one defect per case, the message naming the file (and the line where the reader
can know it) and what is wrong. The line numbers expected are found in the edited text, not
taken from the reader."""
import re

import pytest

from support import SHARED
from mesh.geometry import GeometryError, read_geometry

R67 = SHARED / "data" / "rotor67" / "rotor67geometry.dat"
R37 = SHARED / "data" / "rotor37" / "rotor37geometry.dat"


def _surface(lines, k, pattern=r"^\s*Surface number\s+{k}\b"):
    return next(i for i, line in enumerate(lines) if re.match(pattern.format(k=k), line, re.IGNORECASE))


def _title(lines, k, title):
    """Index of block `title`'s line in rotor 67 surface k."""
    s = _surface(lines, k)
    return next(i for i in range(s, len(lines)) if lines[i].strip() == title)


def _block_end(lines, start):
    """Index after the numeric lines that follow line `start`."""
    i = start + 1
    while i < len(lines) and re.fullmatch(r"[\s\d.eE+-]+", lines[i]) and lines[i].strip():
        i += 1
    return i


def _r67_header(lines):
    return max(i for i, line in enumerate(lines[:_surface(lines, 1)]) if re.match(r"^\s*JM\s+NS", line))


def _set(lines, i, text):
    lines[i] = text
    return i


def r67_no_surface(lines):
    for i, line in enumerate(lines):
        lines[i] = re.sub(r"Surface number", "Surface no.", line)


def r67_no_header(lines):
    h = _r67_header(lines)
    for i in range(h + 1):
        if re.match(r"^\s*JM\s+NS", lines[i]):
            lines[i] = "   (header line dropped)"


def r67_four_numbers(lines):
    _set(lines, _r67_header(lines) + 1, "  110   14   22   16")


def r67_le_after_te(lines):
    _set(lines, _r67_header(lines) + 1, "  110   14   22   85   16")


def r67_ns_13(lines):
    _set(lines, _r67_header(lines) + 1, "  110   13   22   16   85")


def r67_surface_twice(lines):
    return _set(lines, _surface(lines, 14), " Surface number 13 (a copy-paste slip)")


def r67_numbers_before_a_title(lines):
    s = _surface(lines, 2)
    lines.insert(s + 1, "  1.000000")
    return s + 1


def r67_title_twice(lines):
    i = _title(lines, 2, "Radius*Theta Distance")
    return _set(lines, i, " Axial Distance")


def r67_block_missing(lines):
    i = _title(lines, 4, "Delta (Radius*Theta) = Tangential thickness")
    del lines[i:_block_end(lines, i)]


def r67_zero_scale(lines):
    _set(lines, _title(lines, 6, "Radius") + 1, "  0.000000")


def r67_nan(lines):
    i = _title(lines, 6, "Radius") + 3
    lines[i] = "       nan" + lines[i][10:]


def r67_negative_radius(lines):
    i = _title(lines, 6, "Radius") + 4  # values J = 25..32: inside the blade (16..85)
    lines[i] = " -1.000000" + lines[i][10:]


def r37_no_surface(lines):
    for i, line in enumerate(lines):
        lines[i] = line.replace("SURFACE NUMBER", "SURFACE NO.")


def r37_surface_twice(lines):
    return _set(lines, _surface(lines, 6, r"^\s*SURFACE NUMBER\s+{k}\b"), " SURFACE NUMBER     5 FROM THE HUB.")


def r37_four_columns(lines):
    i = _surface(lines, 3, r"^\s*SURFACE NUMBER\s+{k}\b") + 5
    lines[i] = " ".join(lines[i].split()[:4])
    return i


def r37_surface_missing(lines):
    s = _surface(lines, 5, r"^\s*SURFACE NUMBER\s+{k}\b")
    e = _surface(lines, 6, r"^\s*SURFACE NUMBER\s+{k}\b")
    del lines[s:e]


def _rows(lines, k):
    """Indices of the data rows of rotor 37 surface k."""
    s = _surface(lines, k, r"^\s*SURFACE NUMBER\s+{k}\b")
    return list(range(s + 2, _block_end(lines, s + 1)))  # s + 1: the column titles


def r37_truncated(lines):
    rows = _rows(lines, 13)
    del lines[rows[2]:rows[-1] + 1]


def r37_shorter(lines):
    del lines[_rows(lines, 13)[-1]]


def r37_rows_swapped(lines):
    a, b = _rows(lines, 4)[10:12]
    lines[a], lines[b] = lines[b], lines[a]


def _r37_field(lines, k, row, col, value):
    i = _rows(lines, k)[row]
    t = lines[i].split()
    t[col] = value
    lines[i] = "   ".join(t)


def r37_zero_radius(lines):
    _r37_field(lines, 8, 20, 2, "0.0")


def r37_negative_thickness(lines):
    _r37_field(lines, 9, 30, 3, "-0.5")  # THETA 1 far below THETA 2 at J = 31


CASES = [
    (R67, "rotor67", "ft", r67_no_surface, r"no 'Surface number' block found \(not a rotor 67 table\?\)"),
    (R67, "rotor67", "ft", r67_no_header, r"header line 'JM NS NB JLE JTE' with its values not found"),
    (R67, "rotor67", "ft", r67_four_numbers, r"header 'JM NS NB JLE JTE' needs 5 integers, got '110   14   22   16'"),
    (R67, "rotor67", "ft", r67_le_after_te, r"header needs 1 <= JLE < JTE <= JM, got JLE=85, JTE=16, JM=110"),
    (R67, "rotor67", "ft", r67_ns_13, r"surface\(s\) \[14\] beyond NS=13 announced in the header"),
    (R67, "rotor67", "ft", r67_surface_twice, r":{line}: surface 13 appears twice"),
    (R67, "rotor67", "ft", r67_numbers_before_a_title, r":{line}: numbers before any block title in surface 2"),
    (R67, "rotor67", "ft", r67_title_twice, r":{line}: block 'Axial Distance' appears twice in surface 2"),
    (R67, "rotor67", "ft", r67_block_missing, r": surface 4, block 'Tangential thickness' missing"),
    (R67, "rotor67", "ft", r67_zero_scale, r": surface 6, block 'Radius': scale factor must be a positive number, "
                                           r"got 0.0"),
    (R67, "rotor67", "ft", r67_nan, r": surface 6, block 'Radius': non-finite values"),
    (R67, "rotor67", "ft", r67_negative_radius, r": surface 6, block 'Radius': non-positive radius inside the blade"),
    (R37, "rotor37", "cm", r37_no_surface, r"no 'SURFACE NUMBER' block found \(not a rotor 37 table\?\)"),
    (R37, "rotor37", "cm", r37_surface_twice, r":{line}: surface 5 appears twice"),
    (R37, "rotor37", "cm", r37_four_columns, r":{line}: surface 3: expected 5 columns J Z R THETA1 THETA2, found 4"),
    (R37, "rotor37", "cm", r37_surface_missing, r": surface\(s\) 5 missing"),
    (R37, "rotor37", "cm", r37_truncated, r": surface 13 truncated: 2 points"),
    (R37, "rotor37", "cm", r37_shorter, r": surfaces have different point counts .*13: 99"),
    (R37, "rotor37", "cm", r37_rows_swapped, r": surface 4: point numbers J are not 1..100 in order"),
    (R37, "rotor37", "cm", r37_zero_radius, r": surface 8: non-positive radius"),
    (R37, "rotor37", "cm", r37_negative_thickness, r": surface 9: negative thickness \(THETA1 < THETA2\) at point J=31"),
]


@pytest.mark.parametrize("table, fmt, units, damage, message", CASES, ids=[c[3].__name__ for c in CASES])
def test_a_corrupted_table_is_refused_by_name(tmp_path, table, fmt, units, damage, message):
    lines = table.read_text().splitlines()
    line = damage(lines)
    bad = tmp_path / "bad.dat"
    bad.write_text("\n".join(lines) + "\n")
    with pytest.raises(GeometryError) as info:
        read_geometry(bad, fmt, units)
    text = str(info.value)
    assert text.startswith(str(bad)), text
    assert re.search(message.format(line=None if line is None else line + 1), text), text


def test_the_clean_tables_pass_the_same_checks():
    # the cases above are each one defect away from these
    assert len(read_geometry(R67, "rotor67", "ft").sections) == 14
    assert len(read_geometry(R37, "rotor37", "cm").sections) == 13


def test_a_section_the_table_lacks_is_named():
    with pytest.raises(GeometryError, match=r"no surface 15; the table has "):
        read_geometry(R67, "rotor67", "ft").section(15)
