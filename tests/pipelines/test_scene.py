"""Scene parsing: defaults, overrides, and clear errors for bad input."""
import dataclasses
import typing
from pathlib import Path

import pytest

from pipelines.cli import main
from pipelines.scene import SECTIONS, SceneError, load_scene, parse_scene, scene_warnings

ROOT = Path(__file__).resolve().parents[2]


def test_shipped_scenes_parse():
    for name in ("rotor67.toml", "rotor67_coarse.toml"):
        scene = load_scene(ROOT / "scenes" / name)
        assert scene.material.E == pytest.approx(108e9)
        assert scene.blade.tip_section == 13
        assert scene.resolve(scene.blade.geometry).is_file(), scene.blade.geometry


def test_defaults_and_overrides():
    s = parse_scene("[material]\nE = 110e9\nnu = 0.3\n[hbm]\nn_harmonics = 20\n")
    assert (s.material.E, s.material.nu, s.material.rho) == (110e9, 0.3, 4400.0)
    assert s.hbm.n_harmonics == 20 and s.hbm.n_time == 1024
    assert s.casing.n_lobes == 2 and s.contact.mu == 0.15


def test_int_accepted_for_float_but_not_reverse():
    assert parse_scene("[material]\nrho = 4500\n").material.rho == 4500.0
    with pytest.raises(SceneError, match=r"\[hbm\] n_harmonics must be an integer"):
        parse_scene("[hbm]\nn_harmonics = 40.5\n")
    # TOML's true and false are Python ints too: not 1 and 0 harmonics or workers
    with pytest.raises(SceneError, match=r"\[hbm\] n_harmonics must be an integer, got True"):
        parse_scene("[hbm]\nn_harmonics = true\n")
    with pytest.raises(SceneError, match=r"\[isolas\] workers must be an integer, got False"):
        parse_scene("", overrides=["isolas.workers=false"])


def test_a_string_key_takes_the_command_lines_text_as_it_is():
    """--set takes text that is not TOML as a string; a string key takes the text even where
    it reads as TOML (a number, nan), as a file's quoted string would give it."""
    s = parse_scene("", overrides=["name=2024", "material.name=nan", "ti.scheme=massless"])
    assert (s.name, s.material.name, s.ti.scheme) == ("2024", "nan", "massless")
    with pytest.raises(SceneError, match=r"top-level 'name' must be a string, got 2024"):
        parse_scene("name = 2024\n")


def test_a_list_key_takes_one_item_or_commas_on_the_command_line():
    """--set hbm.methods=dlft is the one-item list a user means; items may be given with
    commas and no brackets; a file still needs the list, and a bad item is still named."""
    s = parse_scene("", overrides=["hbm.methods=rl", "isolas.harmonics=1, 3,5", "isolas.amplitudes=2e-3"])
    assert (s.hbm.methods, s.isolas.harmonics, s.isolas.amplitudes) == (("rl",), (1, 3, 5), (2e-3,))
    assert parse_scene("", overrides=["hbm.methods=dlft,rl"]).hbm.methods == ("dlft", "rl")
    assert parse_scene("", overrides=["blade.contact_nodes=7,9", "blade.mesh=x.inp", "blade.units=m"]
                       ).blade.contact_nodes == (7, 9)
    with pytest.raises(SceneError, match=r"\[hbm\] methods must be a list, got 'rl'"):
        parse_scene('[hbm]\nmethods = "rl"\n')
    with pytest.raises(SceneError, match=r"\[isolas\] harmonics must be an integer, got 'x'"):
        parse_scene("", overrides=["isolas.harmonics=1,x"])


def test_an_integer_too_large_for_a_float_is_named():
    with pytest.raises(SceneError, match=r"\[material\] E must be a finite number, got an integer of 400 digits"):
        parse_scene("[material]\nE = " + "9" * 400 + "\n")


@pytest.mark.parametrize("text, message", [
    ("[material]\nyoung = 1e9\n", r"unknown key 'young' in \[material\]"),
    ("[materail]\nE = 1e9\n", r"unknown section \[materail\] .*did you mean 'material'"),
    ("[hbm]\nn_harmonic = 10\n", r"did you mean 'n_harmonics'"),
    ("[material]\nnu = 0.5\n", r"Poisson's ratio nu must lie in"),
    ("[material]\nnu = 0.7\n", r"Poisson's ratio nu must lie in"),
    ("[material]\nE = -1\n", r"Young's modulus"),
    ("[blade]\nunits = \"furlong\"\n", r"unknown length unit 'furlong'"),
    ("[hbm]\nmethods = [\"dlft\", \"xyz\"]\n", r"unknown HBM method 'xyz'"),
    ("[hbm]\nn_harmonics = 40\nn_time = 64\n", r"cannot resolve 40 harmonics"),
    ("[material\nE = 1\n", r"not valid TOML"),
])
def test_bad_scene_is_named(text, message):
    with pytest.raises(SceneError, match=message):
        parse_scene(text)


def test_section_hash_tracks_values_not_text():
    a = parse_scene("[material]\nE = 108e9\n")
    b = parse_scene("# comment\n[material]\nE = 108000000000.0\n")
    c = parse_scene("[material]\nE = 109e9\n")
    assert a.section_hash("material") == b.section_hash("material")
    assert a.section_hash("material") != c.section_hash("material")
    assert a.section_hash("hbm") == c.section_hash("hbm")


# --- every number, found by introspection (a key added later is covered too) ----------
def _numeric(hint) -> str | None:
    """'scalar' or 'list' when a field of this type holds numbers, else None."""
    if hint in (int, float):
        return "scalar"
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin is tuple:
        return "list" if any(_numeric(a) for a in args if a is not Ellipsis) else None
    if args:  # a union: float | None, tuple[int, ...] | None
        kinds = {_numeric(a) for a in args if a is not type(None)} - {None}
        return kinds.pop() if kinds else None
    return None


NUMERIC_KEYS = [(section, f.name, kind) for section, cls in SECTIONS.items()
                for f in dataclasses.fields(cls) if f.init
                for kind in [_numeric(typing.get_type_hints(cls)[f.name])] if kind]


def test_numeric_keys_are_found():
    # the parametrisation below must not silently shrink to nothing
    assert len(NUMERIC_KEYS) >= 40 and ("material", "E", "scalar") in NUMERIC_KEYS
    assert ("render", "window", "list") in NUMERIC_KEYS


@pytest.mark.parametrize("value", ["nan", "inf", "-inf"])
@pytest.mark.parametrize("section, key, kind", NUMERIC_KEYS)
def test_non_finite_number_is_refused_at_load(section, key, kind, value, tmp_path, capsys):
    scene = tmp_path / "scene.toml"
    scene.write_text(f"[{section}]\n{key} = {f'[{value}, 1.0]' if kind == 'list' else value}\n")
    out = tmp_path / "out"
    assert main(["run", str(scene), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.strip().splitlines() == [f"bladerub: error: [{section}] {key} must be a finite number, got "
                                        f"{'[' if kind == 'list' else ''}{float(value)!r}"
                                        f"{', 1.0]' if kind == 'list' else ''}"]
    assert not out.exists(), "nothing may be written for a scene refused at load"


@pytest.mark.parametrize("text, message", [
    ("[rom]\nn_low_modes = -1\n", r"n_low_modes must be >= 0 \(a count of modes\)"),
    ("[render]\nscale = 0\n", r"scale must be > 0 \(the largest displacement drawn"),
    ("[render]\nn_modes = 13\n", r"\[render\] n_modes = 13 exceeds \[fem\] n_modes = 12"),
    ("[ti]\nn_keep = 1\n[casing]\nn_lobes = 1\n",
     r"\[ti\] n_keep = 1 with \[casing\] n_lobes = 1: the periodicity class needs at least 3 Poincare sections"),
    ("[casing]\nn_lobes = 3\n", r"^\[hbm\] n_time = 1024 is not a multiple of \[casing\] n_lobes = 3: the AFT's time grid "
                                  r"would not map onto itself .* take a multiple of 3, e\.g\. 1026$"),
    ("[casing]\nn_lobes = 3\n[hbm]\nsubharmonic = 2\nn_time = 1029\n",
     r"^\[hbm\] n_time = 1029 is not a multiple of \[hbm\] subharmonic x \[casing\] n_lobes = 2 x 3: the AFT's "
     r"time grid .* take a multiple of 6, e\.g\. 1032$"),
    ("[limits]\nmemory_gb = -1\n", r"memory_gb must be >= 0 GB"),
    ("[hbm]\nstability_max_gap = 0\n", r"stability_max_gap must be >= 1 \(1: every point analysed\)"),
    ("[hbm]\nrefine_bifurcations = -1\n", r"refine_bifurcations must be >= 0 \(0: no refinement\), got -1"),
    ("[validation]\nn_scan = 1\n", r"^\[validation\] n_scan must be >= 2, got 1$"),
    ("[isolas]\nomega_min = 2500\n", r"\[isolas\] omega_min = 2500 is not below \[hbm\] omega_max = 2000: the isola "),
    ("[isolas]\nomega_max = 300\n", r"\[hbm\] omega_min = 400 is not below \[isolas\] omega_max = 300"),
    ("[validation]\nisola_tries = 0\n", r"^\[validation\] isola_tries must be >= 1, got 0$"),
    ("[mesh]\nelement_size = 0\n", r"^\[mesh\] element_size must be > 0 m, got 0.0$"),
    ("[mesh]\nn_boundary = 1\n", r"^\[mesh\] n_boundary must be >= 2, got 1$"),
    ("[mesh]\nedge_layers = 0\n", r"^\[mesh\] edge_layers must be >= 1, got 0$"),
    ("[mesh]\nsize_growth = 0\n", r"^\[mesh\] size_growth must be > 0, got 0.0$"),
    ("[blade]\nformat = \"stl\"\n", r"^\[blade\] unknown geometry format 'stl'; known: rotor67, rotor37$"),
    ("[blade]\nrotation = \"up\"\n", r"^\[blade\] unknown rotation 'up'; known: '\+', '-', 'le-leads' "),
    ("[blade]\nhub_section = 5\ntip_section = 5\n", r"^\[blade\] need 1 <= hub_section < tip_section, got 5, 5$"),
    ("[blade]\nhub_section = 0\n", r"^\[blade\] need 1 <= hub_section < tip_section, got 0, "),
    ("[blade]\nmesh = \"  \"\n", r"^\[blade\] mesh must name a mesh file$"),
    ("[casing]\nwidth = 0\n", r"^\[casing\] width must be in \(0, 2 pi\) rad, got 0.0$"),
    ("[casing]\nwidth = 6.3\n", r"^\[casing\] width must be in \(0, 2 pi\) rad, got 6.3$"),
    ("[hbm]\nmethods = [\"dlft\", \"dlft\"]\n", r"^\[hbm\] methods \['dlft', 'dlft'\] names a method twice$"),
    ("[hbm]\nomega_min = 900\nomega_max = 900\n", r"^\[hbm\] need 0 < omega_min < omega_max, got 900.0, 900.0$"),
    ("[hbm]\nstart = \"middle\"\n", r"^\[hbm\] start must be 'omega_min' or 'omega_max', got 'middle'$"),
    ("[ti]\nscheme = \"rk4\"\n", r"^\[ti\] unknown time-integration scheme 'rk4'; known: carpenter, exponential, massless$"),
    ("[ti]\nn_keep = 200\n", r"^\[ti\] need 0 < n_keep < n_revolutions \(the first revolution from rest is never "
                             r"steady\), got n_keep = 200, n_revolutions = 200$"),
    ("[ti]\nomega_min = 901\nomega_max = 900\n", r"^\[ti\] need 0 < omega_min <= omega_max, got 901.0, 900.0$"),
    ("[ti]\nperiodicity_rtol = 1\n", r"^\[ti\] periodicity_rtol must be in \(0, 1\), got 1.0$"),
    ("[ti]\nsettle_rtol = 0.01\n", r"^\[ti\] settle_rtol must be in \(0, periodicity_rtol = 0.01\), got 0.01"),
    ("[render]\nn_modes = -1\n", r"^\[render\] n_modes must be >= 0, got -1$"),
    ("[render]\nhbm_instants = -1\n", r"^\[render\] hbm_instants must be >= 0, got -1$"),
    ("[render]\nhbm_omega = 0\n", r"^\[render\] hbm_omega must be > 0 rad/s, got 0.0$"),
    ("[render]\nwindow = [15, 600]\n", r"^\[render\] window must be \[width, height\] in pixels, got \[15, 600\]$"),
    ("[render]\nwindow = [800]\n", r"^\[render\] window must be \[width, height\] in pixels, got \[800\]$"),
    ("[fem]\nn_fixed_interface_modes = -1\n", r"^\[fem\] n_fixed_interface_modes must be >= 0, got -1$"),
    ("[fem]\ntol = 0.01\n", r"^\[fem\] tol must be in \(0, 1e-2\), got 0.01$"),
    ("[rom]\nn_fixed_modes = -1\n", r"^\[rom\] n_fixed_modes must be >= 0, got -1$"),
    ("[isolas]\nomega_min = 900\nomega_max = 900\n", r"^\[isolas\] need 0 < omega_min < omega_max, got 900.0, 900.0$"),
    ("material = 3\n", r"^\[material\] must be a table$"),
    ("[hbm]\nomega_start = 400\n", r"^\[hbm\] omega_start was renamed to omega_min$"),
    ("[ti]\nomega_end = 400\n", r"^\[ti\] omega_end was renamed to omega_max$"),
])
def test_value_out_of_range_is_named_with_its_reason(text, message):
    with pytest.raises(SceneError, match=message):
        parse_scene(text)


@pytest.mark.parametrize("text", [
    "[mesh]\nn_boundary = 2\nedge_layers = 1\n", "[blade]\nhub_section = 1\ntip_section = 2\n",
    "[casing]\nwidth = 6.28\n", "[ti]\nomega_min = 900\nomega_max = 900\n", "[ti]\nn_keep = 199\n",
    "[ti]\nperiodicity_rtol = 0.999\nsettle_rtol = 0.998\n", "[render]\nwindow = [16, 16]\nn_modes = 0\nhbm_instants = 0\n",
    "[fem]\nn_fixed_interface_modes = 0\ntol = 0.0099\n", "[rom]\nn_fixed_modes = 0\n", "[hbm]\nstart = \"omega_max\"\n",
])
def test_values_at_the_edge_of_their_range_are_taken(text):
    # the other side of each bound above: a check one step too eager would refuse these
    parse_scene(text)


@pytest.mark.parametrize("item, message", [
    ("material.E", r"^--set 'material.E': expected SECTION.KEY=VALUE, e.g. material.E=110e9$"),
    ("material.E=", r"^--set 'material.E=': no value after '='$"),
    ("hbm.n_time=8", r"^\[hbm\] n_time = 8 cannot resolve 40 harmonics \(need n_time >= 2 n_harmonics \+ 2 = 82\) "
                     r"\(command line: --set hbm.n_time=8\)$"),
])
def test_a_bad_command_line_value_is_named_as_typed(item, message):
    with pytest.raises(SceneError, match=message):
        parse_scene("", overrides=[item])


def test_pointless_casing_is_warned():
    assert scene_warnings(parse_scene("")) == []
    flat, = scene_warnings(parse_scene("[casing]\npenetration = 0.0\n"))
    assert "[casing] penetration = 0 m <= 0: the lobes never reach the blade" in flat
    # eq. (28): two lobes of width 1 rad meet at phi = pi / 2, where the Gaussian is still
    # exp(-(pi/2)^2) = 8.48 % of the depth c + p = 5.25e-4 m: d = 4e-4 - 4.45e-5 = 3.55e-4 m
    wide, = scene_warnings(parse_scene("[casing]\nwidth = 1.0\n"))
    assert "width = 1 rad is too wide for 2 lobes" in wide and "back only to 0.000355 m" in wide
