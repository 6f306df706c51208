"""Abaqus / CalculiX input decks (.inp): nodes, solid elements, node sets and *BOUNDARY.

Read here rather than by meshio 5.0, whose Abaqus reader (a) fails on C3D15 (KeyError
'wedge15'), (b) fails on a deck with a second *NODE block (KeyError: the second block
replaces the first's id table), (c) empties a node set that names another set ("A, 3"
gives an empty set), and (d) does not read *BOUNDARY at all, which is how a deck says
where the blade is clamped (all four checked on meshio 5.0.0). What is read:

- *NODE (optionally NSET=): "id, x, y, z" lines; several blocks append. Reals may carry a
  Fortran exponent ("1.5D-3"), which CalculiX reads (checked: the same frequencies).
- *ELEMENT, TYPE=..., (ELSET=): solid elements C3D4, C3D6, C3D8, C3D10, C3D15, C3D20 and
  their variants (C3D8R, C3D10M, C3D20R, ...), data lines continued until the node count is
  complete; other C3Dn types are kept as unknown solids (refused later, by name and line);
  elements of lower dimension (shells, membranes, beams, surfaces) are counted and skipped.
  An *ELEMENT block without data lines (exporters write one per type or section) is dropped.
- *NSET, NSET=... (GENERATE, ELSET=) and *ELSET, ELSET=... (GENERATE): ids or set names;
  GENERATE lines are "first, last[, increment]" (increment 1 when left out, as CalculiX
  reads "20, 24"), and a GENERATE range keeps only the ids the deck defines (CalculiX runs
  a deck whose range crosses gaps in the numbering). Other ids a set names that no *NODE
  defines refuse the deck only where the set is used: in *BOUNDARY or as the root.
  *NSET, ELSET= (Abaqus; CalculiX ignores it) takes the nodes of the set's elements, the
  skipped ones too (a root face marked by S8R or SFM3D8 elements), as element sets may.
  A name in double quotes (NSET="Root Face", as Abaqus writes names with spaces) is the name
  without them, wherever it appears.
- *BOUNDARY (TYPE=DISPLACEMENT, the default): "node or set, first dof[, last dof[, value]]"
  or "node or set, ENCASTRE | PINNED | XSYMM | ...": which translations (dof 1-3) are fixed.
  Fields are read by position: a blank last dof is the first ("ROOT, 1,, 0"). A non-zero
  prescribed value is not a clamp and is refused.
- *INCLUDE, INPUT=...: read in place, relative to the including file, or, where it names
  no file there, to the top deck's folder (CalculiX's rule, from the folder it runs in).
Keywords, parameters and set names are case-insensitive (names are kept in upper case);
a UTF-8 byte order mark is skipped.
Refused, by name, rather than skipped (a skipped one would silently give another blade):
decks with *PART/*INSTANCE (Abaqus/CAE's default, with the way out); keywords that make or
move nodes or elements from others (*NGEN, *NFILL, *NCOPY, *NMAP, *SYSTEM, *ELGEN, *ELCOPY);
INPUT= on *NODE, *ELEMENT, *NSET, *ELSET and *BOUNDARY (data lines in another file, which
CalculiX does not read there either: write them in the deck or *INCLUDE them); a keyword
line continued on the next one (ending in "," before a line of parameters), which
CalculiX rejects as well. A keyword line merely ending in "," is read, as CalculiX does.
Refused too, naming both lines: a node id or an element id defined twice, a skipped
element's too (two meshes written with overlapping numbering; CalculiX refuses the element,
a shell with a solid's id as well, and keeps the last coordinates of the node without a
word). A skipped element's line is read for its id only: one element a line.
"""
from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np

from mesh.source import MeshImportError, SolidBlock, SourceMesh

SOLID_TYPES = {4: "tetra", 6: "wedge", 8: "hexahedron", 10: "tetra10", 15: "wedge15", 20: "hexahedron20"}
_SOLID = re.compile(r"^C3D(\d+)")
# Abaqus shorthands of *BOUNDARY and the dof they fix (only 1-3, translations, matter here)
_SHORTHAND = {"ENCASTRE": (1, 2, 3), "PINNED": (1, 2, 3), "XSYMM": (1,), "YSYMM": (2,), "ZSYMM": (3,),
              "XASYMM": (2, 3), "YASYMM": (1, 3), "ZASYMM": (1, 2)}
# keywords that make or move nodes or elements from others: not read, so refused (skipping
# one would import another blade without a word), with what each does
_GENERATORS = {"NGEN": "generates nodes", "NFILL": "generates nodes", "NCOPY": "copies nodes",
               "NMAP": "maps node coordinates", "SYSTEM": "moves the *NODE lines that follow into a local frame",
               "ELGEN": "generates elements", "ELCOPY": "copies elements"}
# keywords read here whose data lines INPUT= would take from another file (not read: refused)
_WITH_DATA = ("NODE", "ELEMENT", "NSET", "ELSET", "BOUNDARY")


def _keyword_lines(path: Path, seen: tuple[Path, ...] = ()):
    """(file, line number, text) of the deck with *INCLUDEs inlined; comments and blanks dropped."""
    path = Path(path)
    if path.resolve() in seen:
        raise MeshImportError(f"{path}: *INCLUDE loop")
    try:
        text = path.read_text(encoding="utf-8-sig", errors="replace")  # -sig: a BOM would hide a first *NODE
    except OSError as exc:
        raise MeshImportError(f"cannot read {path}: {exc}") from exc
    for no, line in enumerate(text.splitlines(), 1):
        s = line.strip()
        if not s or s.startswith("**"):
            continue
        if s.startswith("*") and s[1:].split(",")[0].strip().upper() == "INCLUDE":
            params = _params(s)
            if "INPUT" not in params:
                raise MeshImportError(f"{path}:{no}: *INCLUDE without INPUT=")
            inc = _include_path(params["INPUT"], path, seen)
            if not inc.is_file():
                raise MeshImportError(f"{path}:{no}: included file not found: {inc}"
                                      + _also_tried(params["INPUT"], path, seen))
            yield from _keyword_lines(inc, seen + (path.resolve(),))
            continue
        yield path, no, s


def _include_path(name: str, path: Path, seen: tuple[Path, ...]) -> Path:
    """The file an *INCLUDE, INPUT=name of `path` reads: relative to `path`'s folder, or,
    where no such file exists, to the top deck's (seen[0]; CalculiX resolves every INPUT=
    from the folder it runs in, usually the top deck's, so a nested include written for it
    names its file from there)."""
    inc = Path(name.strip('"'))
    if inc.is_absolute():
        return inc
    here = path.parent / inc
    if here.is_file() or not seen:
        return here
    top = seen[0].parent / inc
    return top if top.is_file() else here


def _also_tried(name: str, path: Path, seen: tuple[Path, ...]) -> str:
    inc = Path(name.strip('"'))
    if inc.is_absolute() or not seen or seen[0].parent == path.parent.resolve():
        return ""
    return f" (nor {seen[0].parent / inc}, from the top deck's folder)"


def included_files(path: Path, seen: tuple[Path, ...] = ()) -> list[Path]:
    """The files a deck includes, recursively, in the order they are read."""
    path = Path(path)
    if path.resolve() in seen:
        raise MeshImportError(f"{path}: *INCLUDE loop")
    out = []
    text = path.read_text(encoding="utf-8-sig", errors="replace")
    if "*include" not in text.lower():  # the common case, 20x faster than the regex on a big deck
        return out
    for m in re.finditer(r"(?im)^[ \t]*\*include[ \t]*,(.*)$", text):
        inc = _include_path(_params("*INCLUDE," + m.group(1)).get("INPUT", ""), path, seen)
        if inc.is_file():
            out.append(inc)
            out.extend(included_files(inc, seen + (path.resolve(),)))
    return out


def _unquoted(name: str) -> str:
    """A name without the double quotes Abaqus needs around one with spaces ("Root Face")."""
    name = name.strip()
    return name[1:-1].strip() if len(name) >= 2 and name[0] == name[-1] == '"' else name


def _params(line: str) -> dict:
    """Keyword line parameters: {'TYPE': 'C3D15', 'GENERATE': ''}; keys in upper case,
    values without their quotes (NSET="Root Face" is the set Root Face)."""
    out = {}
    for word in line.split(",")[1:]:
        k, _, v = word.partition("=")
        if k.strip():
            out[k.strip().upper()] = _unquoted(v)
    return out


def _blocks(path: Path):
    """(keyword, params, data lines, where) for each keyword of the deck."""
    keyword, params, data, where, line = None, {}, [], "", ""
    for f, no, s in _keyword_lines(path):
        if s.startswith("*"):
            if keyword is not None:
                yield keyword, params, data, where
            keyword = s[1:].split(",")[0].strip().upper()
            params, data, where, line = _params(s), [], f"{f.name}:{no}", s
        elif keyword is not None:
            if not data:
                _refuse_continuation(line, s, where)
            data.append(s)
    if keyword is not None:
        yield keyword, params, data, where


def _refuse_continuation(keyword_line: str, first_data: str, where: str) -> None:
    """Abaqus continues a keyword line that ends in "," on the next line; CalculiX does not
    (it stops at the parameters as data), and reading them as data here would misread the
    block, so a continued line is refused. A trailing "," before real data lines (which
    never hold "=") is harmless and CalculiX reads it: left alone."""
    if keyword_line.rstrip().endswith(",") and "=" in first_data:
        raise MeshImportError(f"{where}: keyword line '{keyword_line}' is continued on the next line "
                              f"('{first_data}'); CalculiX does not read continued keyword lines either: "
                              "write the keyword and all its parameters on one line")


def _refuse_unread(keyword: str, params: dict, where: str) -> None:
    """Keywords (and INPUT= data files) that would change the nodes or elements but are not
    read here: refused by name, so that a deck is never imported as another blade."""
    if keyword in _GENERATORS:
        raise MeshImportError(f"{where}: *{keyword} {_GENERATORS[keyword]}, which bladerub does not read; "
                              "write the nodes and elements out explicitly (e.g. the deck your pre-processor "
                              "or CalculiX's cgx writes)")
    if keyword in _WITH_DATA and "INPUT" in params:
        raise MeshImportError(f"{where}: *{keyword}, INPUT={params['INPUT']}: data lines in another file are "
                              f"not read (nor by CalculiX); write them under *{keyword} or *INCLUDE a file "
                              "that holds the keyword line and its data")


_D_TO_E = str.maketrans("dD", "eE")


def _fortran_exponents(text: str) -> str:
    """Reals with a Fortran exponent letter ("1.5D-3", "2.d0") spelled with an E: CalculiX
    and Abaqus read them (Fortran formatted input), numpy and float() do not."""
    return text.translate(_D_TO_E) if "d" in text or "D" in text else text


def _float(token: str) -> float:
    """A real of a data line, Fortran exponents included (ValueError if it is none)."""
    return float(_fortran_exponents(token))


def _numbers(lines: list[str], dtype, where: str) -> np.ndarray:
    """All comma-separated numbers of a data block, fast (a C parse of the joined lines);
    a token that is not a number is named from a line-by-line parse. Reals may carry a
    Fortran exponent (1.0D-3)."""
    text = ",".join(line.rstrip().rstrip(",") for line in lines)
    if not text:
        return np.zeros(0, dtype=dtype)
    is_int = np.dtype(dtype).kind == "i"
    if not is_int:
        text = _fortran_exponents(text)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # numpy warns, then stops, at the first non-number
        try:
            out = np.fromstring(text, dtype=dtype, sep=",")
            if out.size == text.count(",") + 1:
                return out
        except (DeprecationWarning, ValueError):
            pass
    convert = int if is_int else _float
    for line in lines:
        for t in line.split(","):
            if t.strip():
                try:
                    convert(t)
                except ValueError:
                    raise MeshImportError(f"{where}: '{t.strip()}' is not a number ({line.strip()})") from None
    raise MeshImportError(f"{where}: cannot read the data lines as numbers")


def _skipped_ids(lines: list[str], where: str) -> list[int]:
    """Element ids of a skipped (non-solid) *ELEMENT block: the first number of each line.
    One element a line: no shell, membrane, beam or surface element has the 16 entries
    after which a line is continued, and a trailing "," (some exporters end every line
    with one) does not continue it here."""
    try:
        return [int(line.split(",", 1)[0]) for line in lines]
    except ValueError:
        raise MeshImportError(f"{where}: element lines need an integer id first") from None


def _skipped_nodes(skipped: list, wanted: set) -> list[int]:
    """Node ids of the skipped elements whose id is in `wanted`. skipped: (data lines, where)
    of each skipped *ELEMENT block, parsed only when an *NSET, ELSET= asks (it is rare)."""
    out = []
    for lines, where in skipped:
        for eid, line in zip(_skipped_ids(lines, where), lines):
            if eid in wanted:
                out.extend(int(t) for t in line.split(",")[1:] if t.strip())
    return out


def _tokens(lines: list[str]) -> list[str]:
    return [t.strip() for line in lines for t in line.split(",") if t.strip()]


def _generate(lines: list[str], where: str) -> list[int]:
    """Ids of GENERATE data lines, read one line at a time as "first, last[, increment]":
    the increment is optional (1 when missing or blank, as CalculiX reads "20, 24"), so the
    numbers of a block cannot be cut into threes."""
    out = []
    for line in lines:
        t = [x.strip() for x in line.split(",")]
        while len(t) > 2 and not t[-1]:
            t.pop()  # a trailing ","
        try:
            if len(t) not in (2, 3):
                raise ValueError
            first, last = int(t[0]), int(t[1])
            step = int(t[2]) if len(t) == 3 and t[2] else 1
        except ValueError:
            raise MeshImportError(f"{where}: GENERATE needs 'first, last[, increment]' lines, got '{line}'") from None
        if step < 0 or last < first:
            raise MeshImportError(f"{where}: GENERATE line '{line}' needs first <= last and a positive increment")
        out.extend(range(first, last + 1, step or 1))
    return out


def _set_members(lines: list[str], params: dict, sets: dict, kind: str, where: str) -> tuple[list, list]:
    """Members of an *NSET/*ELSET data block: (ids listed or from named sets, ids from GENERATE
    ranges). sets: name -> (listed ids, generated ids) of the sets defined so far. The two
    are kept apart because a GENERATE range may cross ids the deck does not define."""
    if "GENERATE" in params:
        return [], _generate(lines, where)
    listed, generated = [], []
    for t in map(_unquoted, _tokens(lines)):
        if re.fullmatch(r"[+-]?\d+", t):
            listed.append(int(t))
        elif t.upper() in sets:
            listed.extend(sets[t.upper()][0])
            generated.extend(sets[t.upper()][1])
        else:
            raise MeshImportError(f"{where}: unknown {kind} '{t}'")
    return listed, generated


def _boundary_line(line: str, where: str) -> tuple[str, tuple[int, ...]]:
    """(node or set, fixed translations) of a *BOUNDARY data line, its fields read by
    position: "ROOT, 1,, 0" has a blank last dof (= the first), not the value in its place."""
    t = [_unquoted(x) for x in line.split(",")]
    if len(t) < 2 or not t[0] or not t[1]:
        raise MeshImportError(f"{where}: *BOUNDARY line '{line}' names no dof")
    if t[1].upper() in _SHORTHAND:
        return t[0], _SHORTHAND[t[1].upper()]
    try:
        first = int(t[1])
        last = int(t[2]) if len(t) > 2 and t[2] else first
        value = _float(t[3]) if len(t) > 3 and t[3] else 0.0
    except ValueError:
        raise MeshImportError(f"{where}: cannot read *BOUNDARY line '{line}'") from None
    if value != 0.0:
        raise MeshImportError(f"{where}: *BOUNDARY '{line}' prescribes a non-zero "
                              "displacement; only a clamp (0) can define the root")
    return t[0], tuple(d for d in range(first, last + 1) if d <= 3)


def read_deck(path: Path) -> SourceMesh:
    """Read an Abaqus/CalculiX deck into a SourceMesh (node sets by upper-case name, ids as in the file)."""
    path = Path(path)
    node_chunks, node_set_ids, elem_set_ids = [], {}, {}  # set name -> (listed ids, GENERATE'd ids)
    elements = []  # (type, ids (k,), node ids (k, n), where)
    ignored, skipped = {}, []  # skipped: (data lines, where) of non-solid elements, for sets
    skipped_ids = []  # (ordinal of the *ELEMENT block, numbers per line, ids): checked for repeats
    boundary = []  # (node id or set name, dofs, where)
    node_blocks, element_blocks = [], []  # (ordinal of the *NODE / *ELEMENT block, numbers per record)
    ordinal = {"NODE": -1, "ELEMENT": -1}
    for keyword, params, data, where in _blocks(path):
        if keyword in ordinal:
            ordinal[keyword] += 1
        if keyword in ("PART", "INSTANCE", "ASSEMBLY"):
            raise MeshImportError(
                f"{where}: *{keyword}: decks with parts and assemblies are not supported; write a flat "
                "deck (Abaqus/CAE: model attributes, 'Do not use parts and assemblies in input files')")
        _refuse_unread(keyword, params, where)
        if keyword == "NODE":
            if "SYSTEM" in params and params["SYSTEM"].upper() != "R":
                raise MeshImportError(f"{where}: *NODE, SYSTEM={params['SYSTEM']}: only rectangular coordinates")
            vals = _numbers(data, np.float64, where)
            if vals.size != 4 * len(data):
                bad = next((line for line in data if len([t for t in line.split(",") if t.strip()]) != 4), "")
                raise MeshImportError(f"{where}: *NODE lines need 'id, x, y, z', got '{bad.strip()}'")
            arr = vals.reshape(-1, 4)
            if arr.size:
                node_chunks.append(arr)
                node_blocks.append((ordinal["NODE"], 4))
                if "NSET" in params:
                    node_set_ids.setdefault(params["NSET"].upper(), ([], []))[0].extend(arr[:, 0].astype(np.int64))
        elif keyword == "ELEMENT":
            etype = params.get("TYPE", "").upper()
            if not etype:
                raise MeshImportError(f"{where}: *ELEMENT without TYPE=")
            if not data:  # an empty block: neither a type of the blade nor something skipped
                if "ELSET" in params:
                    elem_set_ids.setdefault(params["ELSET"].upper(), ([], []))
                continue
            m = _SOLID.match(etype)
            if m is None:  # skipped, but a set may name its elements (a root skin of S8R...)
                ignored[etype] = ignored.get(etype, 0) + len(data)
                skipped.append((data, where))
                ids = _skipped_ids(data, where)
                skipped_ids.append((ordinal["ELEMENT"], len(_tokens(data[:1])), np.asarray(ids, dtype=np.int64)))
                if "ELSET" in params:
                    elem_set_ids.setdefault(params["ELSET"].upper(), ([], []))[0].extend(ids)
                continue
            n = int(m.group(1))
            vals = _numbers(data, np.int64, where)
            if vals.size % (n + 1):
                raise MeshImportError(f"{where}: *ELEMENT, TYPE={etype}: {vals.size} numbers are not "
                                      f"whole elements of {n} nodes plus an id")
            vals = vals.reshape(-1, n + 1)
            elements.append((SOLID_TYPES.get(n, etype), vals[:, 0], vals[:, 1:], where))
            element_blocks.append((ordinal["ELEMENT"], n + 1))
            if "ELSET" in params:
                elem_set_ids.setdefault(params["ELSET"].upper(), ([], []))[0].extend(vals[:, 0])
        elif keyword == "NSET":
            name = params.get("NSET", "").upper()
            if not name:
                raise MeshImportError(f"{where}: *NSET without NSET=")
            if "ELSET" in params:
                es = params["ELSET"].upper()
                if es not in elem_set_ids:
                    raise MeshImportError(f"{where}: *NSET, ELSET={es}: unknown element set")
                wanted = np.concatenate([np.asarray(v, dtype=np.int64) for v in elem_set_ids[es]])
                ids = [e[2][np.isin(e[1], wanted)].ravel() for e in elements]
                entry = node_set_ids.setdefault(name, ([], []))
                entry[0].extend(np.concatenate(ids) if ids else [])
                entry[0].extend(_skipped_nodes(skipped, set(wanted.tolist())))
            listed, generated = _set_members(data, params, node_set_ids, "node set", where)
            entry = node_set_ids.setdefault(name, ([], []))
            entry[0].extend(listed)
            entry[1].extend(generated)
        elif keyword == "ELSET":
            name = params.get("ELSET", "").upper()
            if not name:
                raise MeshImportError(f"{where}: *ELSET without ELSET=")
            listed, generated = _set_members(data, params, elem_set_ids, "element set", where)
            entry = elem_set_ids.setdefault(name, ([], []))
            entry[0].extend(listed)
            entry[1].extend(generated)
        elif keyword == "BOUNDARY":
            if params.get("TYPE", "DISPLACEMENT").upper() != "DISPLACEMENT":
                continue
            for line in data:
                boundary.append((*_boundary_line(line, where), where))

    if not node_chunks:
        raise MeshImportError(f"{path}: no *NODE lines")
    nodes = np.vstack(node_chunks)
    node_ids = nodes[:, 0].astype(np.int64)
    if not np.array_equal(nodes[:, 0], node_ids):
        raise MeshImportError(f"{path}: node ids must be integers")
    order = np.argsort(node_ids, kind="stable")
    if (node_ids[order][1:] == node_ids[order][:-1]).any():
        later, first = _first_repeat(node_ids)
        same = np.array_equal(nodes[later, 1:], nodes[first, 1:])
        at = [_record_line(path, "NODE", node_blocks, [len(c) for c in node_chunks], k) for k in (later, first)]
        raise MeshImportError(
            f"{at[0]}: node id {int(node_ids[later])} is defined twice, first at {at[1]}"
            f"{' (same coordinates)' if same else ', with other coordinates'}: two meshes written with "
            "overlapping numbering? Renumber one so that every *NODE id is defined once")
    _refuse_repeated_elements(path, [(*b, e[1]) for b, e in zip(element_blocks, elements)] + skipped_ids)

    def index(ids, what):
        ids = np.asarray(ids, dtype=np.int64)
        pos = np.clip(np.searchsorted(node_ids[order], ids), 0, len(order) - 1)
        ok = node_ids[order][pos] == ids
        if not ok.all():
            missing = np.unique(ids[~ok])
            raise MeshImportError(f"{path}: {what} refer to node ids not in the deck: "
                                  f"{missing[:10].tolist()}{' ...' if missing.size > 10 else ''}")
        return order[pos]

    blocks = []
    for etype, ids, conn, where in elements:
        blocks.append(SolidBlock(etype, index(conn, f"*ELEMENT, TYPE {etype} ({where})"), ids, where))
    # blocks of one type are merged: one block per type, in order of first appearance
    merged = {}
    for b in blocks:
        merged.setdefault(b.type, []).append(b)
    blocks = tuple(SolidBlock(t, np.concatenate([b.connectivity for b in bs]), np.concatenate([b.ids for b in bs]),
                              bs[0].where) for t, bs in merged.items())
    node_sets, unknown_ids = _resolve_node_sets(node_set_ids, node_ids, index)
    fixed = np.zeros((len(nodes), 3), dtype=bool)
    for target, dofs, where in boundary:
        if re.fullmatch(r"[+-]?\d+", target):
            idx = index([int(target)], f"*BOUNDARY ({where})")
        elif target.upper() in unknown_ids:
            missing = unknown_ids[target.upper()]
            raise MeshImportError(f"{where}: *BOUNDARY set '{target}' names node ids not in the deck: "
                                  f"{missing[:10].tolist()}{' ...' if missing.size > 10 else ''}")
        elif target.upper() in node_sets:
            idx = node_sets[target.upper()]
        else:
            raise MeshImportError(f"{where}: *BOUNDARY names an unknown node set '{target}'")
        for d in dofs:
            fixed[idx, d - 1] = True
    return SourceMesh(points=np.ascontiguousarray(nodes[:, 1:]), node_ids=node_ids, blocks=blocks,
                      node_sets=node_sets, fixed=fixed, ignored=ignored,
                      files=(path, *included_files(path)), unknown_ids=unknown_ids)


def _refuse_repeated_elements(path: Path, blocks: list) -> None:
    """Refuse an element id defined twice, solid or skipped (a shell whose id a solid already
    has): the deck is broken (two meshes written with overlapping numbering), and CalculiX
    refuses it ("*ERROR reading *ELEMENT", a shell's id too), and a set naming the id would
    take both elements' nodes. Both lines are named; they are looked up only then, by reading
    the deck again. blocks: (ordinal of the *ELEMENT block, numbers per record, ids) for each
    block read, solid or skipped, in any order."""
    blocks = sorted(blocks, key=lambda b: b[0])  # file order
    if not blocks:
        return
    ids = np.concatenate([b[2] for b in blocks])
    if np.unique(ids).size == ids.size:
        return
    later, first = _first_repeat(ids)
    at = [_record_line(path, "ELEMENT", [b[:2] for b in blocks], [len(b[2]) for b in blocks], k)
          for k in (later, first)]
    raise MeshImportError(f"{at[0]}: element id {int(ids[later])} is defined twice, first at {at[1]}: two meshes "
                          "written with overlapping numbering? Renumber one so that every *ELEMENT id is defined once")


def _first_repeat(ids: np.ndarray) -> tuple[int, int]:
    """(position of the first id, in file order, that an earlier one repeats; position of
    that earlier one). ids must hold a repeat."""
    uniq, first = np.unique(ids, return_index=True)
    defined = np.zeros(ids.size, dtype=bool)
    defined[first] = True
    later = int(np.flatnonzero(~defined)[0])
    return later, int(first[np.searchsorted(uniq, ids[later])])


def _record_line(path: Path, keyword: str, blocks: list, sizes: list, k: int) -> str:
    """"file:line" where record k of the deck's *NODE or *ELEMENT records (in file order,
    over the blocks read) begins. blocks: (ordinal of the block among the deck's blocks of
    that keyword, numbers per record) for each block read; sizes: their records. The deck is
    read again: lines are not kept while reading (a large deck has millions)."""
    starts = np.cumsum([0] + list(sizes))
    b = int(np.searchsorted(starts, k, side="right")) - 1
    wanted, width = blocks[b]
    skip = (k - int(starts[b])) * width  # numbers before the record in its block
    seen, inside, count = -1, False, 0
    for f, no, s in _keyword_lines(path):
        if s.startswith("*"):
            if inside:
                break
            if s[1:].split(",")[0].strip().upper() == keyword:
                seen += 1
                inside = seen == wanted
            continue
        if inside:
            count += len([t for t in s.split(",") if t.strip()])
            if count > skip:
                return f"{f.name}:{no}"
    return path.name  # the deck changed since it was read: its name, at least


def _resolve_node_sets(node_set_ids: dict, node_ids: np.ndarray, index) -> tuple[dict, dict]:
    """Node sets as node indices, and the ids each names that the deck does not define.

    A GENERATE range keeps the ids the deck defines (CalculiX runs a deck whose "1, 120"
    crosses gaps in the numbering); other unknown ids are set aside, not refused: a set the
    blade does not use (in *BOUNDARY or as the root) must not refuse the deck, as CalculiX
    runs it. index: node ids -> node indices (all known)."""
    node_sets, unknown_ids = {}, {}
    for name, (listed, generated) in node_set_ids.items():
        listed = np.asarray(listed, dtype=np.int64)
        generated = np.asarray(generated, dtype=np.int64)
        known = np.isin(listed, node_ids)
        if not known.all():
            unknown_ids[name] = np.unique(listed[~known])
        ids = np.concatenate([listed[known], generated[np.isin(generated, node_ids)]])
        node_sets[name] = np.unique(index(ids, f"node set {name}"))
    return node_sets, unknown_ids
