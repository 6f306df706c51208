"""Blade geometry tables -> blade sections in SI units.

Two NASA layouts are read:

- ``rotor67``: "ROTOR 67 GEOMETRY FOR EXPORT" (NASA Lewis, 1991/92). A header line
  ``JM NS NB JLE JTE`` with its values, then NS streamsurfaces ("Surface number k"), each
  with four blocks -- axial distance, radius*theta of the upper surface, tangential
  thickness, radius -- every block a scale factor followed by JM numbers. The blade lies
  between points JLE and JTE (1-based); the lower surface is upper minus thickness.
- ``rotor37``: NASA TP-1659 Table IV. "SURFACE NUMBER k" blocks of rows
  ``J Z R THETA1 THETA2`` (Z, R in the table's length unit, THETA in rad); the whole row
  range is the blade, THETA1 is taken as the upper surface.

Both end up as `BladeGeometry`: one `Section` per streamsurface with the blade part only
(LE to TE), in metres, and the full meridional lines (hub/casing) where the table has them.

Length unit: each table says its unit in the text before the data (rotor 67: "THE
DIMENSIONS ARE IN FEET.", rotor 37: "Z and R are in centimeters"); see `stated_unit`. The
reader takes that unit, refuses a caller's unit that contradicts it, and asks for one when
the table states none.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mesh.options import KNOWN_FORMATS, KNOWN_UNITS


class GeometryError(ValueError):
    """A geometry table that cannot be read as the announced layout (names file, surface, block)."""


@dataclass(frozen=True)
class Section:
    """One blade section on a streamsurface, from leading edge (index 0) to trailing edge.

    number: 1-based streamsurface number in the table (1 = hub).
    z: (n,) axial position, m. r: (n,) radius, m.
    rtheta_upper: (n,) radius * angle of the upper (suction) surface, m.
    thickness: (n,) tangential thickness r * (theta_upper - theta_lower), m (>= 0).
    """

    number: int
    z: np.ndarray
    r: np.ndarray
    rtheta_upper: np.ndarray
    thickness: np.ndarray

    @property
    def theta_upper(self) -> np.ndarray:
        """(n,) angle of the upper surface, rad."""
        return self.rtheta_upper / self.r

    @property
    def theta_lower(self) -> np.ndarray:
        """(n,) angle of the lower surface, rad."""
        return (self.rtheta_upper - self.thickness) / self.r

    def _xyz(self, theta: np.ndarray) -> np.ndarray:
        return np.stack([self.r * np.cos(theta), self.r * np.sin(theta), self.z], axis=1)

    def upper_xyz(self) -> np.ndarray:
        """(n, 3) upper surface points in the global frame (z = rotation axis), m."""
        return self._xyz(self.theta_upper)

    def lower_xyz(self) -> np.ndarray:
        """(n, 3) lower surface points in the global frame, m."""
        return self._xyz(self.theta_lower)

    def camber_xyz(self) -> np.ndarray:
        """(n, 3) camber line points (mean angle of upper and lower surfaces), m."""
        return self._xyz(0.5 * (self.theta_upper + self.theta_lower))

    def meridional_arc(self) -> np.ndarray:
        """(n,) cumulative meridional arc length sqrt(dz^2 + dr^2) from the LE, m."""
        ds = np.hypot(np.diff(self.z), np.diff(self.r))
        return np.concatenate([[0.0], np.cumsum(ds)])

    def area(self) -> float:
        """Blade section area on the streamsurface: integral of thickness over meridional arc, m^2."""
        return float(np.trapz(self.thickness, self.meridional_arc()))


@dataclass(frozen=True)
class StatedUnit:
    """A table's own statement of its length unit.

    unit: the KNOWN_UNITS key. word: the word the table uses ("FEET", "centimeters").
    line: 1-based line number of the statement. text: that line, stripped.
    """

    unit: str
    word: str
    line: int
    text: str


@dataclass(frozen=True)
class BladeGeometry:
    """Blade sections of one table, SI units.

    sections: tuple of `Section`, hub (first) to outermost surface of the table.
    n_blades: number of blades of the rotor.
    meridional_z, meridional_r: (n_surfaces, m) full streamsurface lines (including the
        up/downstream extensions where the table has them), m; rows match `sections`.
    source: the table file.
    units: the length unit the table's numbers were read in (a KNOWN_UNITS key).
    stated: where the table states its unit, or None when it states none (then `units` is
        the caller's).
    """

    sections: tuple[Section, ...]
    n_blades: int
    meridional_z: np.ndarray
    meridional_r: np.ndarray
    source: Path
    units: str
    stated: StatedUnit | None

    def section(self, number: int) -> Section:
        """The section of the 1-based streamsurface `number`."""
        for s in self.sections:
            if s.number == number:
                return s
        raise GeometryError(f"{self.source}: no surface {number}; the table has "
                            f"{self.sections[0].number}..{self.sections[-1].number}")

    def surface_radius(self, number: int, z) -> np.ndarray:
        """Radius of streamsurface `number` at axial positions z (m), linear in the table, m."""
        i = [s.number for s in self.sections].index(number)
        zz, rr = self.meridional_z[i], self.meridional_r[i]
        order = np.argsort(zz, kind="stable")
        return np.interp(z, zz[order], rr[order])


def read_geometry(path: Path | str, format: str = "rotor67", units: str | None = None) -> BladeGeometry:
    """Read a NASA blade table. Raises GeometryError naming the problem and where it is.

    units: the table's length unit, one of KNOWN_UNITS. None (the default) takes the unit
    the table states before its data: both NASA tables state theirs, so a guessed default
    could only be right for one of them (rotor 37 read in feet is 30 times too large). A
    unit that contradicts the table's statement, or None for a table that states none, is
    refused.
    """
    path = Path(path)
    if format not in KNOWN_FORMATS:
        raise GeometryError(f"unknown geometry format '{format}'; known: {', '.join(KNOWN_FORMATS)}")
    if units is not None and units not in KNOWN_UNITS:
        raise GeometryError(f"unknown length unit '{units}' for {path}; known: {', '.join(KNOWN_UNITS)}")
    if not path.is_file():
        raise GeometryError(f"geometry table not found: {path}")
    lines = path.read_text(errors="replace").splitlines()
    if format == "rotor67":
        return _read_rotor67(lines, path, units)
    return _read_rotor37(lines, path, units)


# --- the table's length unit ----------------------------------------------------------

_UNIT_WORDS = {
    "ft": ("feet", "foot", "ft"),
    "in": ("inches", "inch", "in"),
    "cm": ("centimeters", "centimetres", "centimeter", "centimetre", "cm"),
    "mm": ("millimeters", "millimetres", "millimeter", "millimetre", "mm"),
    "m": ("meters", "metres", "meter", "metre", "m"),
}
_UNIT_OF_WORD = {w: unit for unit, words in _UNIT_WORDS.items() for w in words}
_UNIT_WORD = "|".join(sorted(_UNIT_OF_WORD, key=len, reverse=True))
#: a sentence whose subject is the table's lengths: "THE DIMENSIONS ARE IN FEET.", "Z and R
#: are in centimeters", "all coordinates given in mm". A bare quantity ("about 0.024
#: inches", rotor 67's tip clearance) is not a statement of the table's unit.
_UNIT_SENTENCE = re.compile(
    r"\b(?:dimensions|coordinates|lengths|distances|[a-z](?:\s*,\s*[a-z])*\s+and\s+[a-z])\s+"
    r"(?:(?:are|is)\s+)?(?:(?:given|expressed|measured|listed)\s+)?in\s+"
    rf"(?P<word>{_UNIT_WORD})\b", re.IGNORECASE)
#: a title giving the unit alone in parentheses: "Rotor 37 blade geometry (centimeters)"
_UNIT_TITLE = re.compile(rf"\(\s*(?P<word>{_UNIT_WORD})\s*\)", re.IGNORECASE)


def stated_unit(lines: list[str], path: Path) -> StatedUnit | None:
    """The length unit the table's text before the data (`lines`, from line 1) states, or
    None. Two statements of different units are refused: the table contradicts itself."""
    found = []
    for lineno, line in enumerate(lines, start=1):
        for pattern in (_UNIT_SENTENCE, _UNIT_TITLE):
            for m in pattern.finditer(line):
                word = m.group("word")
                found.append(StatedUnit(_UNIT_OF_WORD[word.lower()], word, lineno, line.strip()))
    if not found:
        return None
    first = found[0]
    other = next((s for s in found if s.unit != first.unit), None)
    if other is not None:
        raise GeometryError(f"{path}: the table states two length units: {first.word} on line {first.line} "
                            f"('{first.text}') and {other.word} on line {other.line} ('{other.text}'); "
                            "correct the table")
    return first


def table_unit(lines: list[str], path: Path, units: str | None) -> tuple[str, StatedUnit | None]:
    """(unit the table is read in, the table's statement) from the text before the data
    (`lines`) and the caller's `units` (None: the table's)."""
    stated = stated_unit(lines, path)
    if units is None:
        if stated is None:
            raise GeometryError(f"{path}: the table does not state its length unit (no line such as "
                                "'THE DIMENSIONS ARE IN FEET' before the data); set [blade] units to one of "
                                f"{', '.join(KNOWN_UNITS)}")
        return stated.unit, stated
    if stated is not None and stated.unit != units:
        raise GeometryError(f"{path}:{stated.line}: the table states its lengths in {stated.word} "
                            f"('{stated.text}', that is units = \"{stated.unit}\"), but [blade] units = "
                            f"\"{units}\"; leave units out or set it to \"{stated.unit}\"")
    return units, stated


def _check_stations(z: np.ndarray, r: np.ndarray, path: Path, where: str, j0: int) -> None:
    """The blade's stations must advance along the axis, LE to TE: a repeated point (zero
    meridional step) or one that goes back would fold the section (and divide by zero in
    the edge sizing). j0: the table's point number J of z[0]."""
    dz = np.diff(z)
    bad = np.flatnonzero(~(dz > 0))
    if bad.size:
        j = j0 + int(bad[0]) + 1
        what = "repeated station" if dz[bad[0]] == 0 and r[bad[0] + 1] == r[bad[0]] else "axial distance not increasing"
        raise GeometryError(f"{path}: {where}: {what} at point J={j} ({z[bad[0]]:.6g} m then "
                            f"{z[bad[0] + 1]:.6g} m; the blade's stations must advance from LE to TE)")


def _check_span_order(sections: list[Section], path: Path, j0: int) -> None:
    """Each surface must lie above the one below it at every station J of the blade: a
    repeated or out-of-order surface folds the lofted solid (gmsh then fails after tens of
    seconds with overlapping facets, or does not return at all). The sections have equal
    point counts, J matching J across surfaces (the tables' grid); j0: the table's point
    number J of the LE."""
    for lower, upper in zip(sections, sections[1:]):
        step = upper.r - lower.r
        if np.all(step > 0):
            continue
        j = int(np.argmax(~(step > 0)))
        what = "repeats the radius of" if step[j] == 0 else "lies below"
        raise GeometryError(f"{path}: surface {upper.number} {what} surface {lower.number} at point "
                            f"J={j0 + j}: radius {upper.r[j]:.6g} m against {lower.r[j]:.6g} m; "
                            "the surfaces must go outward from hub to casing (a duplicated or misnumbered surface?)")


# --- rotor 67 -------------------------------------------------------------------------

_BLOCKS = ("axial", "rtheta", "thickness", "radius")
_BLOCK_TITLES = {"axial": "Axial Distance", "rtheta": "Radius*Theta Distance",
                 "thickness": "Tangential thickness", "radius": "Radius"}
_SURFACE = re.compile(r"^\s*surface\s+number\s+(\d+)", re.IGNORECASE)
_HEADER = re.compile(r"^\s*JM\s+NS\s+NB\s+JLE\s+JTE\s*$")


def _block_name(line: str) -> str | None:
    """Which rotor 67 block a title line opens (order of the checks matters: titles overlap)."""
    low = line.lower()
    if "axial" in low:
        return "axial"
    if "thickness" in low:
        return "thickness"
    if "theta" in low:
        return "rtheta"
    if low.strip() == "radius":
        return "radius"
    return None


def _numbers(line: str) -> list[float] | None:
    """The floats of a data line, or None if any token is not a number."""
    try:
        return [float(t) for t in line.split()]
    except ValueError:
        return None


def _read_rotor67(lines: list[str], path: Path, units: str | None) -> BladeGeometry:
    # Header: the last "JM NS NB JLE JTE" title before the first surface, values on the next line.
    first_surface = next((i for i, l in enumerate(lines) if _SURFACE.match(l)), None)
    if first_surface is None:
        raise GeometryError(f"{path}: no 'Surface number' block found (not a rotor 67 table?)")
    units, stated = table_unit(lines[:first_surface], path, units)
    scale = KNOWN_UNITS[units]
    header = [i for i, l in enumerate(lines[:first_surface]) if _HEADER.match(l)]
    if not header or header[-1] + 1 >= first_surface:
        raise GeometryError(f"{path}: header line 'JM NS NB JLE JTE' with its values not found")
    values = _numbers(lines[header[-1] + 1])
    if values is None or len(values) != 5 or any(v != int(v) for v in values):
        raise GeometryError(f"{path}: header 'JM NS NB JLE JTE' needs 5 integers, "
                            f"got '{lines[header[-1] + 1].strip()}'")
    jm, ns, nb, jle, jte = (int(v) for v in values)
    if not (1 <= jle < jte <= jm):
        raise GeometryError(f"{path}: header needs 1 <= JLE < JTE <= JM, got JLE={jle}, JTE={jte}, JM={jm}")

    # Walk the surfaces: titles switch the current block, numeric lines feed it.
    surfaces: dict[int, dict[str, list[tuple[int, list[float]]]]] = {}
    current: dict[str, list] | None = None
    block = None
    number = None
    for lineno, line in enumerate(lines[first_surface:], start=first_surface + 1):
        if not line.strip():
            continue
        m = _SURFACE.match(line)
        if m:
            number = int(m.group(1))
            if number in surfaces:
                raise GeometryError(f"{path}:{lineno}: surface {number} appears twice")
            current = surfaces[number] = {}
            block = None
            continue
        nums = _numbers(line)
        if nums is not None:
            if block is None:
                raise GeometryError(f"{path}:{lineno}: numbers before any block title in surface {number}")
            current[block].append((lineno, nums))
            continue
        name = _block_name(line)
        if name is None:
            where = f"surface {number}, block '{_BLOCK_TITLES[block]}'" if block else f"surface {number}"
            raise GeometryError(f"{path}:{lineno}: non-numeric data in {where}: '{line.strip()}'")
        if name in current:
            raise GeometryError(f"{path}:{lineno}: block '{_BLOCK_TITLES[name]}' appears twice in surface {number}")
        block = name
        current[block] = []

    expected = list(range(1, ns + 1))
    missing = [k for k in expected if k not in surfaces]
    if missing:
        raise GeometryError(f"{path}: surface(s) {', '.join(map(str, missing))} missing; "
                            f"header announces NS={ns}, found {sorted(surfaces)}")
    extra = [k for k in surfaces if k not in expected]
    if extra:
        raise GeometryError(f"{path}: surface(s) {extra} beyond NS={ns} announced in the header")

    arrays = {}
    for k in expected:
        for name in _BLOCKS:
            where = f"{path}: surface {k}, block '{_BLOCK_TITLES[name]}'"
            if name not in surfaces[k]:
                raise GeometryError(f"{where} missing")
            flat = [v for _, nums in surfaces[k][name] for v in nums]
            if len(flat) != jm + 1:  # scale factor + JM values
                state = "truncated" if len(flat) < jm + 1 else "too long"
                raise GeometryError(f"{where} {state}: expected a scale factor and {jm} values "
                                    f"(JM), found {len(flat)} numbers")
            factor, data = flat[0], np.asarray(flat[1:])
            if not np.isfinite(factor) or factor <= 0:
                raise GeometryError(f"{where}: scale factor must be a positive number, got {factor}")
            if not np.all(np.isfinite(data)):
                raise GeometryError(f"{where}: non-finite values")
            arrays[k, name] = factor * data * scale

    blade = slice(jle - 1, jte)
    sections = []
    for k in expected:
        t = arrays[k, "thickness"][blade]
        r = arrays[k, "radius"][blade]
        if np.any(t < 0):
            j = jle + int(np.argmax(t < 0))
            raise GeometryError(f"{path}: surface {k}, block 'Tangential thickness': negative thickness "
                                f"{t[j - jle] / scale:g} at point J={j} inside the blade (JLE={jle}..JTE={jte})")
        if np.any(r <= 0):
            raise GeometryError(f"{path}: surface {k}, block 'Radius': non-positive radius inside the blade")
        _check_stations(arrays[k, "axial"][blade], r, path, f"surface {k}, block 'Axial Distance'", jle)
        sections.append(Section(number=k, z=arrays[k, "axial"][blade], r=r,
                                rtheta_upper=arrays[k, "rtheta"][blade], thickness=t))
    _check_span_order(sections, path, jle)
    mz = np.stack([arrays[k, "axial"] for k in expected])
    mr = np.stack([arrays[k, "radius"] for k in expected])
    return BladeGeometry(sections=tuple(sections), n_blades=nb, meridional_z=mz, meridional_r=mr, source=path,
                         units=units, stated=stated)


# --- rotor 37 -------------------------------------------------------------------------

_R37_SURFACE = re.compile(r"^\s*SURFACE\s+NUMBER\s+(\d+)", re.IGNORECASE)


def _read_rotor37(lines: list[str], path: Path, units: str | None) -> BladeGeometry:
    first_surface = next((i for i, l in enumerate(lines) if _R37_SURFACE.match(l)), None)
    if first_surface is None:
        raise GeometryError(f"{path}: no 'SURFACE NUMBER' block found (not a rotor 37 table?)")
    units, stated = table_unit(lines[:first_surface], path, units)
    scale = KNOWN_UNITS[units]
    surfaces: dict[int, list[list[float]]] = {}
    rows = None
    number = None
    for lineno, line in enumerate(lines, start=1):
        if not line.strip():
            continue
        m = _R37_SURFACE.match(line)
        if m:
            number = int(m.group(1))
            if number in surfaces:
                raise GeometryError(f"{path}:{lineno}: surface {number} appears twice")
            rows = surfaces[number] = []
            continue
        if rows is None:
            continue  # title lines before the first surface
        nums = _numbers(line)
        if nums is None:
            if re.match(r"^\s*J\s+Z\s+R\s+THETA", line, re.IGNORECASE):
                continue
            raise GeometryError(f"{path}:{lineno}: non-numeric data in surface {number}: '{line.strip()}'")
        if len(nums) != 5:
            raise GeometryError(f"{path}:{lineno}: surface {number}: expected 5 columns J Z R THETA1 THETA2, "
                                f"found {len(nums)}")
        rows.append(nums)
    numbers = sorted(surfaces)
    missing = [k for k in range(1, numbers[-1] + 1) if k not in surfaces]
    if missing:
        raise GeometryError(f"{path}: surface(s) {', '.join(map(str, missing))} missing")
    sizes = {k: len(surfaces[k]) for k in numbers}
    sections = []
    for k in numbers:
        a = np.asarray(surfaces[k], dtype=float)
        if a.shape[0] < 3:
            raise GeometryError(f"{path}: surface {k} truncated: {a.shape[0]} points")
        if not np.all(np.isfinite(a)):
            row = int(np.flatnonzero(~np.all(np.isfinite(a), axis=1))[0])
            raise GeometryError(f"{path}: surface {k}: non-finite value at row {row + 1} of the surface")
        j = a[:, 0]
        if not np.array_equal(j, np.arange(1, a.shape[0] + 1)):
            raise GeometryError(f"{path}: surface {k}: point numbers J are not 1..{a.shape[0]} in order "
                                "(truncated or shuffled section)")
        z, r, t1, t2 = a[:, 1] * scale, a[:, 2] * scale, a[:, 3], a[:, 4]
        if np.any(r <= 0):
            raise GeometryError(f"{path}: surface {k}: non-positive radius")
        _check_stations(z, r, path, f"surface {k}", 1)
        # THETA1 is the upper surface when the blade is of positive thickness t1 - t2.
        t = r * (t1 - t2)
        if np.any(t < -1e-12):
            jj = int(np.argmax(t < -1e-12)) + 1
            raise GeometryError(f"{path}: surface {k}: negative thickness (THETA1 < THETA2) at point J={jj}")
        sections.append(Section(number=k, z=z, r=r, rtheta_upper=r * t1, thickness=np.maximum(t, 0.0)))
    if len(set(sizes.values())) != 1:
        raise GeometryError(f"{path}: surfaces have different point counts {sizes} (truncated section?)")
    _check_span_order(sections, path, 1)
    mz = np.stack([s.z for s in sections])
    mr = np.stack([s.r for s in sections])
    return BladeGeometry(sections=tuple(sections), n_blades=36, meridional_z=mz, meridional_r=mr, source=path,
                         units=units, stated=stated)
