"""Scenes: a TOML file (plus command-line overrides) -> one frozen, validated `Scene`.

Every configurable number of the pipeline lives in a frozen dataclass owned by the
package that uses it (`mesh.options`, `fem.material`, ...). This module is the one
place that maps TOML sections onto those dataclasses; the dataclass defaults are the
scene defaults. Unknown sections or keys are errors that name the key (and the
closest known one), so a misspelt key never silently falls back to a default.

Overrides (`bladerub run SCENE --set material.E=110e9`) are merged into the file's
tables before validation, so they are checked exactly as the file is; a scene with
overrides carries the fully resolved TOML (`resolved_toml`) as its text, which is what
its artifacts record.
"""
from __future__ import annotations

import dataclasses
import difflib
import hashlib
import json
import math
import tomllib
import typing
from pathlib import Path

from fem.material import Material
from fem.options import FemOptions
from hbm.isolas.options import IsolaOptions
from hbm.options import CasingOptions, ContactOptions, HbmOptions, TimeIntegrationOptions, ValidationOptions
from mesh.options import BladeOptions, MeshOptions
from rom.options import RomOptions
from pipelines.options import LimitOptions, RenderOptions


class SceneError(ValueError):
    """A scene file that cannot be used as written."""


SECTIONS: dict[str, type] = {
    "blade": BladeOptions,
    "mesh": MeshOptions,
    "material": Material,
    "fem": FemOptions,
    "rom": RomOptions,
    "casing": CasingOptions,
    "contact": ContactOptions,
    "hbm": HbmOptions,
    "ti": TimeIntegrationOptions,
    "isolas": IsolaOptions,
    "validation": ValidationOptions,
    "render": RenderOptions,
    "limits": LimitOptions,
}


@dataclasses.dataclass(frozen=True)
class Scene:
    """A parsed scene. `path` is the TOML file; relative paths in it resolve from its folder."""

    name: str
    path: Path
    text: str
    blade: BladeOptions
    mesh: MeshOptions
    material: Material
    fem: FemOptions
    rom: RomOptions
    casing: CasingOptions
    contact: ContactOptions
    hbm: HbmOptions
    ti: TimeIntegrationOptions
    isolas: IsolaOptions
    validation: ValidationOptions
    render: RenderOptions
    limits: LimitOptions

    def resolve(self, p: str | Path) -> Path:
        """A path of the scene, made absolute relative to the scene file's folder."""
        p = Path(p).expanduser()
        return p if p.is_absolute() else (self.path.parent / p).resolve()

    @property
    def fixed_interface_modes(self) -> int:
        """Fixed-interface modes the fem stage computes: max([fem] n_fixed_interface_modes,
        [rom] n_fixed_modes), so that one factorisation of K serves the ROM. A stage key of
        its own: fem.h5 changes with this count, not with either key alone."""
        return max(self.fem.n_fixed_interface_modes, self.rom.n_fixed_modes)

    @property
    def n_contact_nodes(self) -> int:
        """Contact nodes the blade will have: those [blade] contact_nodes lists for a mesh
        file, else [mesh] n_boundary (snapped onto the tip face). The stages' cost estimates
        read this, not n_boundary, which a listed set overrides (mesh.imported.import_blade)."""
        listed = self.blade.contact_nodes
        return len(listed) if listed is not None else self.mesh.n_boundary

    def section_hash(self, *names: str) -> str:
        """Hash of the named sections' values (defaults included): what a stage depends on."""
        payload = {n: _jsonable(dataclasses.asdict(getattr(self, n))) for n in names}
        return hashlib.sha256(json.dumps(payload, sort_keys=True).encode()).hexdigest()

    def value(self, key: str):
        """The value named by `key`: "section" (its fields as a dict), "section.field" (one
        field), or "section~field~field" (the section without those fields)."""
        if "." in key:
            section, field = key.split(".", 1)
            return _jsonable(getattr(getattr(self, section), field))
        section, *dropped = key.split("~")
        obj = getattr(self, section)
        if not dataclasses.is_dataclass(obj):
            return _jsonable(obj)
        return {k: v for k, v in _jsonable(dataclasses.asdict(obj)).items() if k not in dropped}

    def key_hash(self, key: str) -> str:
        """Hash of value(key) (defaults included): what a stage depends on."""
        return hashlib.sha256(json.dumps(self.value(key), sort_keys=True).encode()).hexdigest()


def _jsonable(d):
    if isinstance(d, dict):
        return {k: _jsonable(v) for k, v in d.items()}
    if isinstance(d, (list, tuple)):
        return [_jsonable(v) for v in d]
    if isinstance(d, Path):
        return str(d)
    return d


def _suggest(word: str, choices) -> str:
    close = difflib.get_close_matches(word, list(choices), n=1)
    return f" (did you mean '{close[0]}'?)" if close else ""


def _owners(key: str, besides: str = "") -> list[str]:
    """The sections (but `besides`) that have a key `key`."""
    return [sec for sec, cls in SECTIONS.items()
            if sec != besides and key in {f.name for f in dataclasses.fields(cls) if f.init}]


def _elsewhere(key: str, section: str) -> str:
    """" (a key of [ti])" when `key`, unknown in [section], is a key of other sections, else ""."""
    owners = [f"[{sec}]" for sec in _owners(key, section)]
    return f" (a key of {' and '.join(owners)}, not of [{section}])" if owners else ""


#: list keys whose empty list means something: no seeds around the primary NFRC
MAY_BE_EMPTY = {("isolas", "primary_amplitudes")}


def _coerce(cls: type, section: str, key: str, value, hint):
    """Check a TOML value against the dataclass field's annotation; ints are accepted for floats."""
    where = f"[{section}] {key}"
    origin = typing.get_origin(hint)
    if hint is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise SceneError(f"{where} must be a number, got {value!r}")
        try:
            return float(value)
        except OverflowError:  # an integer past 1.8e308
            raise SceneError(f"{where} must be a finite number, got an integer of {len(str(abs(value)))} digits") \
                from None
    if hint is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise SceneError(f"{where} must be an integer, got {value!r}")
        return value
    if hint is bool:
        if not isinstance(value, bool):
            raise SceneError(f"{where} must be true or false, got {value!r}")
        return value
    if hint is str:
        if not isinstance(value, str):
            raise SceneError(f"{where} must be a string, got {value!r}")
        return value
    if origin is tuple:
        if not isinstance(value, list):
            raise SceneError(f"{where} must be a list, got {value!r}")
        # an empty list means nothing for every other list key (hbm.methods = [] ran no NFRC)
        if not value and (section, key) not in MAY_BE_EMPTY:
            raise SceneError(f"{where} must list at least one value, got []")
        args = typing.get_args(hint)
        item = args[0] if args else float
        return tuple(_coerce(cls, section, key, v, item) for v in value)
    if origin in (typing.Union, getattr(__import__("types"), "UnionType", None)):
        args = [a for a in typing.get_args(hint) if a is not type(None)]
        if len(args) == 1:  # an optional key (float | None): its type's own message says what it takes
            return _coerce(cls, section, key, value, args[0])
        for a in args:
            try:
                return _coerce(cls, section, key, value, a)
            except SceneError:
                pass
        raise SceneError(f"{where}: {value!r} is not a valid value")
    return value


#: Keys renamed since earlier versions: (section, old) -> new.
RENAMED = {("hbm", "omega_start"): "omega_min", ("hbm", "omega_end"): "omega_max",
           ("ti", "omega_start"): "omega_min", ("ti", "omega_end"): "omega_max"}


def _non_finite(value) -> bool:
    """True if `value` (a TOML value: number, string, list, table) holds a NaN or an infinity."""
    if isinstance(value, float):
        return not math.isfinite(value)
    if isinstance(value, list):
        return any(_non_finite(v) for v in value)
    if isinstance(value, dict):
        return any(_non_finite(v) for v in value.values())
    return False


def _build_section(name: str, cls: type, table: dict):
    if not isinstance(table, dict):
        raise SceneError(f"[{name}] must be a table")
    hints = typing.get_type_hints(cls)
    fields = {f.name for f in dataclasses.fields(cls) if f.init}
    kwargs = {}
    for key, value in table.items():
        if (name, key) in RENAMED:
            raise SceneError(f"[{name}] {key} was renamed to {RENAMED[name, key]}")
        if key not in fields:
            raise SceneError(f"unknown key '{key}' in [{name}]{_elsewhere(key, name) or _suggest(key, fields)}; "
                             f"known keys: {', '.join(sorted(fields))}")
        # Every number of every section, whatever its type: no option of the pipeline means
        # anything at NaN or infinity, and a range check `x < 0` lets NaN through.
        if _non_finite(value):
            raise SceneError(f"[{name}] {key} must be a finite number, got {value!r}")
        kwargs[key] = _coerce(cls, name, key, value, hints[key])
    try:
        return cls(**kwargs)
    except (ValueError, TypeError) as exc:
        raise SceneError(f"[{name}] {exc}") from exc


def parse_override(item: str) -> tuple[str, str, object]:
    """"section.key=value" (or "name=value") -> (section, key, value).

    The value is read as a TOML value (110e9, 0.1, true, "dlft", ["dlft", "rl"]); text that
    is not one (omega_min, le-leads, +) is taken as a string, so strings need no quotes on a
    command line. A list key also takes one item or items separated by commas, with or without
    brackets (hbm.methods=dlft, hbm.methods=[dlft,rl], isolas.harmonics=1,2,3). Raises
    SceneError naming the item.
    """
    if "=" not in item:
        raise SceneError(f"--set {item!r}: expected SECTION.KEY=VALUE, e.g. material.E=110e9")
    lhs, raw = (part.strip() for part in item.split("=", 1))
    if lhs == "name":
        section, key = "", "name"
    else:
        section, dot, key = lhs.partition(".")
        if not dot or not section or not key or "." in key:
            raise SceneError(f"--set {item!r}: expected SECTION.KEY=VALUE, e.g. material.E=110e9")
        if section not in SECTIONS:
            raise SceneError(f"--set {item!r}: unknown section [{section}]{_suggest(section, SECTIONS)}; "
                             f"known sections: {', '.join(SECTIONS)}")
        fields = {f.name for f in dataclasses.fields(SECTIONS[section]) if f.init}
        if key not in fields and (section, key) not in RENAMED:
            raise SceneError(f"--set {item!r}: unknown key '{key}' in [{section}]"
                             f"{_elsewhere(key, section) or _suggest(key, fields)}; "
                             f"known keys: {', '.join(sorted(fields))}")
    if not raw:
        raise SceneError(f"--set {item!r}: no value after '='")
    if not _is_text(raw):  # bytes that are not UTF-8 on the command line (surrogate escapes)
        raise SceneError(f"--set {item!r}: the value is not UTF-8 text")
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw
    if not isinstance(value, str) and _is_string_key(section, key):
        value = raw  # name=2024, material.name=nan: text, as the key expects
    if not isinstance(value, list) and _is_list_key(section, key):
        if isinstance(value, str):
            # [dlft,rl] without quotes is no TOML list: the brackets as the user meant them
            items = raw[1:-1] if raw.startswith("[") and raw.endswith("]") else raw
            value = [_item(part.strip()) for part in items.split(",")]
        else:
            value = [value]
    return section, key, value


def _is_text(text: str) -> bool:
    """Whether `text` can be written as UTF-8 (no lone surrogates, which Python makes of
    command-line bytes that are not UTF-8)."""
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        return False
    return True


def _item(text: str):
    """One item of a list given without brackets: a TOML value, else text."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


def _is_list_key(section: str, key: str) -> bool:
    if not section:
        return False
    hint = typing.get_type_hints(SECTIONS[section]).get(key)
    return any(typing.get_origin(h) is tuple for h in (hint, *typing.get_args(hint)))


def _is_string_key(section: str, key: str) -> bool:
    if not section:
        return key == "name"
    hint = typing.get_type_hints(SECTIONS[section]).get(key)
    return hint is str or set(typing.get_args(hint)) == {str, type(None)}  # str | None: a path, a unit


def _merge_overrides(data: dict, overrides) -> dict:
    for item in overrides:
        section, key, value = parse_override(item)
        if not section:
            data[key] = value
            continue
        table = data.setdefault(section, {})
        if not isinstance(table, dict):
            raise SceneError(f"[{section}] must be a table")
        table[key] = value
    return data


def parse_scene(text: str, path: Path | str = Path("scene.toml"), overrides=()) -> Scene:
    """Parse scene TOML text, with "section.key=value" overrides applied over it.

    Raises SceneError naming the offending section, key or override. With overrides, the
    Scene's text is the resolved TOML (every value, the overrides included).
    """
    path = Path(path).resolve()
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{path}: not valid TOML: {exc}") from exc
    overrides = tuple(overrides)
    data = _merge_overrides(data, overrides)
    name = data.pop("name", path.stem)
    if not isinstance(name, str):
        raise SceneError(f"top-level 'name' must be a string, got {name!r}")
    for key in data:
        if key not in SECTIONS and not isinstance(data[key], dict):  # a key above every [section]
            owners = _owners(key)
            hint = f" (a key of [{owners[0]}]: write it below that section's header)" if len(owners) == 1 else ""
            raise SceneError(f"unknown top-level key '{key}' in {path}{hint}; the only top-level key is 'name', "
                             f"the others belong in sections: {', '.join(SECTIONS)}")
        if key not in SECTIONS:
            raise SceneError(f"unknown section [{key}]{_suggest(key, SECTIONS)} in {path}; "
                             f"known sections: {', '.join(SECTIONS)}")
    parts = {}
    for sec, cls in SECTIONS.items():
        try:
            parts[sec] = _build_section(sec, cls, data.get(sec, {}))
        except SceneError as exc:
            given = [o for o in overrides if o.split("=", 1)[0].strip().startswith(f"{sec}.")]
            if given:  # say where the value came from when the command line set keys of this section
                raise SceneError(f"{exc} (command line: {', '.join('--set ' + o for o in given)})") from exc
            raise
    scene = Scene(name=name, path=path, text=text, **parts)
    try:
        _check_combinations(scene)
    except SceneError as exc:
        if overrides:
            raise SceneError(f"{exc} (command line: {', '.join('--set ' + o for o in overrides)})") from exc
        raise
    if overrides:
        header = f"# {path.name} with " + " ".join(f"--set {o}" for o in overrides)
        scene = dataclasses.replace(scene, text=resolved_toml(scene, header))
    return scene


def _check_combinations(scene: Scene) -> None:
    """Values valid one by one that cannot work together: a SceneError naming both keys."""
    if scene.render.n_modes > scene.fem.n_modes:
        raise SceneError(f"[render] n_modes = {scene.render.n_modes} exceeds [fem] n_modes = {scene.fem.n_modes}: "
                         f"only {scene.fem.n_modes} modes are computed to be drawn")
    if scene.ti.n_keep * scene.casing.n_lobes < 2:
        raise SceneError(f"[ti] n_keep = {scene.ti.n_keep} with [casing] n_lobes = {scene.casing.n_lobes}: the "
                         "periodicity class needs at least 3 Poincare sections (n_keep n_lobes + 1)")
    # The casing repeats every T / n_l; the AFT grid spans nu T (the basis period), so the
    # turn is N_t / (nu n_l) samples: a whole number or the residual loses the symmetry.
    n, nu = scene.casing.n_lobes, scene.hbm.subharmonic
    if scene.hbm.n_time % (nu * n):
        up = -(-scene.hbm.n_time // (nu * n)) * nu * n
        what = f"[casing] n_lobes = {n}" if nu == 1 else f"[hbm] subharmonic x [casing] n_lobes = {nu} x {n}"
        raise SceneError(f"[hbm] n_time = {scene.hbm.n_time} is not a multiple of {what}: the AFT's "
                         f"time grid would not map onto itself under the casing's symmetry (a turn of 1/{n} of a "
                         f"revolution), so the NFRC's branch points become imperfect ones and the branch wanders "
                         f"onto orbits of broken symmetry; take a multiple of {nu * n}, e.g. {up}")
    lo, hi = scene.isolas.omega_range(scene.hbm)
    if not lo < hi:  # one of the two set in [isolas], the other taken from [hbm]
        def where(key):
            own = getattr(scene.isolas, key) is not None
            return f"[{'isolas' if own else 'hbm'}] {key} = {lo if key == 'omega_min' else hi:g}"
        raise SceneError(f"{where('omega_min')} is not below {where('omega_max')}: the isola search's "
                         "speed range is empty")


def scene_warnings(scene: Scene) -> list[str]:
    """Values that are valid but make (part of) the run pointless; the CLI prints each once.

    Casing, eq. (28) of the reference paper: d_j = c - (c + p) exp(-(phi / w)^2), so the
    lobe's deepest point is at d = -p, and neighbouring lobes meet at phi = +-pi / n_l,
    where d should be back at the clearance c: exp(-(pi / (n_l w))^2) < 1 % needs
    w < pi / (2.146 n_l).
    """
    out = []
    c = scene.casing
    if c.penetration <= 0:
        out.append(f"[casing] penetration = {c.penetration:g} m <= 0: the lobes never reach the blade's "
                   f"circular path (the casing stays >= {-c.penetration:g} m away from it), so nothing excites "
                   "the blade and every NFRC point is the blade at rest")
    tail = (c.clearance + c.penetration) * math.exp(-((math.pi / c.n_lobes) / c.width) ** 2)
    if tail > 0.01 * (c.clearance + c.penetration):
        out.append(f"[casing] width = {c.width:g} rad is too wide for {c.n_lobes} lobes: they overlap, so between "
                   f"them the casing comes back only to {c.clearance - tail:.3g} m from the blade's path instead of "
                   f"the clearance {c.clearance:g} m, with a kink where they meet (width below "
                   f"{math.pi / c.n_lobes / 2.146:.3g} rad keeps the overlap under 1 % of the lobe depth)")
    return out


def load_scene(path: Path | str, overrides=()) -> Scene:
    """Read and parse a scene file, with "section.key=value" overrides (see parse_override)."""
    path = Path(path)
    if path.is_dir():
        raise SceneError(f"the scene {path} is a folder, not a scene file: give a TOML file "
                         f"(e.g. {path / 'scene.toml'})")
    if not path.is_file():
        raise SceneError(f"scene file not found: {path}")
    try:
        raw = path.read_bytes()
    except OSError as exc:  # permissions, an I/O error: a bad scene, nothing computed
        raise SceneError(f"cannot read the scene file {path}: {exc.strerror or exc}") from None
    try:
        text = raw.decode("utf-8")  # TOML is UTF-8 whatever the locale
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        column = exc.start - (raw.rfind(b"\n", 0, exc.start) + 1) + 1
        raise SceneError(f"{path}: not valid TOML: byte 0x{raw[exc.start]:02x} at line {line}, column {column} "
                         "is not UTF-8 (save the file as UTF-8)") from None
    # a byte-order mark, which Windows editors put before UTF-8 text: not TOML, but not the
    # user's content either (tomllib called it "Invalid statement (at line 1, column 1)")
    return parse_scene(text.removeprefix("\ufeff"), path, overrides)


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)  # Python's repr of a float is a TOML float (1e-07, 108000000000.0, inf)
    if isinstance(v, (str, Path)):
        # JSON string escapes are TOML's; JSON leaves DEL as it is, which TOML does not allow
        return json.dumps(str(v), ensure_ascii=False).replace("\x7f", "\\u007f")
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"no TOML form for {v!r}")


def _comment(text: str) -> str:
    """`text` as one TOML comment line: a newline or another control character (from a --set
    value) escaped as in a TOML string, since a comment may hold neither."""
    text = "".join(json.dumps(c)[1:-1] if (ord(c) < 0x20 and c != "\t") else "\\u007f" if c == "\x7f" else c
                   for c in text)
    return text if text.startswith("#") else f"# {text}"


def resolved_toml(scene: Scene, header: str = "") -> str:
    """The scene with every key written out (defaults included), as TOML text that
    parse_scene reads back to the same values. Keys whose value is None (unset optional
    keys) are left out: TOML has no null, and leaving them out means the same thing."""
    lines = [_comment(header)] if header else []
    lines.append(f"name = {_toml_value(scene.name)}")
    for section, cls in SECTIONS.items():
        obj = getattr(scene, section)
        lines.append(f"\n[{section}]")
        for f in dataclasses.fields(cls):
            value = getattr(obj, f.name)
            if f.init and value is not None:
                lines.append(f"{f.name} = {_toml_value(value)}")
            elif f.init:
                lines.append(f"# {f.name}: unset")
    return "\n".join(lines) + "\n"
