"""What a user meets first: scene files and --set values that the scene module must refuse
with one line (exit 2, nothing created), and `bladerub show` output that must stay valid
TOML reading back to the same scene, whatever text the values hold."""
import tomllib
from pathlib import Path

import pytest

from pipelines.cli import main
from pipelines.scene import SECTIONS, load_scene, parse_scene

ROOT = Path(__file__).resolve().parents[2]
COARSE = ROOT / "scenes" / "rotor67_coarse.toml"


def _refused(argv, out: Path, capsys) -> str:
    """Run the CLI, assert exit 2 with one line and nothing created; returns the line."""
    assert main(argv) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1, lines
    assert not out.exists(), "nothing may be written for a scene refused at load"
    return lines[0]


def _same_scene(a, b) -> None:
    assert a.name == b.name
    for section in SECTIONS:
        assert getattr(a, section) == getattr(b, section), section


@pytest.mark.parametrize("value", ["Ti\nx", "Ti\rx", "Ti\x1bx", "Ti\x7fx"])
def test_show_with_a_control_character_in_a_set_value_prints_toml_that_reads_back(value, tmp_path, capsys):
    """A newline in a --set value ended the header comment (the rest of the line was read as a
    key), and DEL (which JSON leaves raw, TOML forbids) was printed raw in the header and the
    value: `bladerub show` printed text that is not TOML."""
    assert main(["show", str(COARSE), "--set", f"material.name={value}"]) == 0
    text = capsys.readouterr().out
    tomllib.loads(text)  # raises on invalid TOML
    back = parse_scene(text, COARSE)
    assert back.material.name == value
    _same_scene(back, load_scene(COARSE, [f"material.name={value}"]))
    # the text a run records in its artifacts (the scene read back to name changed keys)
    recorded = load_scene(COARSE, [f"material.name={value}"]).text
    assert parse_scene(recorded, COARSE).material.name == value


def test_show_of_a_file_string_holding_del_reads_back(tmp_path, capsys):
    scene = tmp_path / "s.toml"
    scene.write_text('name = "a\\u007fb"\n[material]\nname = "Ti\\u007f"\n')
    assert main(["show", str(scene)]) == 0
    text = capsys.readouterr().out
    back = parse_scene(text, scene)
    assert (back.name, back.material.name) == ("a\x7fb", "Ti\x7f")


def test_a_scene_file_not_in_utf8_is_named_with_the_place(tmp_path, capsys):
    """A Latin-1 comment used to give `'utf-8' codec can't decode byte 0xe9 in position 16:
    invalid continuation byte`, naming neither the file nor the line."""
    scene = tmp_path / "latin1.toml"
    scene.write_bytes(b"[material]\n# caf\xe9\nE = 1e9\n")
    out = tmp_path / "out"
    line = _refused(["run", str(scene), "--out", str(out), "--until", "mesh"], out, capsys)
    assert line == (f"bladerub: error: {scene}: not valid TOML: byte 0xe9 at line 2, column 6 is not UTF-8 "
                    "(save the file as UTF-8)")


def test_a_scene_saved_with_a_byte_order_mark_reads_as_without(tmp_path, capsys):
    """Windows editors may save UTF-8 with a byte-order mark: the run was refused with "not
    valid TOML: Invalid statement (at line 1, column 1)", a line that names nothing the user
    wrote."""
    text = COARSE.read_text()
    plain, marked = tmp_path / "plain.toml", tmp_path / "marked.toml"
    plain.write_text(text, encoding="utf-8")
    marked.write_text(text, encoding="utf-8-sig")
    assert marked.read_bytes()[:3] == b"\xef\xbb\xbf"
    shown = []
    for path in (plain, marked):
        assert main(["show", str(path)]) == 0
        shown.append(capsys.readouterr().out.splitlines()[1:])  # after the line naming the file
    assert shown[0] == shown[1] and any(line.startswith("name = ") for line in shown[0])


def test_a_set_value_that_is_not_utf8_is_named_before_the_folder_is_made(tmp_path, capsys):
    """Command-line bytes that are not UTF-8 (surrogate escapes in Python) used to pass the
    scene, create the folder and its lock, then fail with `'utf-8' codec can't encode
    character '\\udcff' ...`, naming no key."""
    out = tmp_path / "out"
    line = _refused(["run", str(COARSE), "--out", str(out), "--until", "mesh", "--set", "material.name=Ti\udcff"],
                    out, capsys)
    assert line == "bladerub: error: --set 'material.name=Ti\\udcff': the value is not UTF-8 text"


@pytest.mark.parametrize("section, key", [("hbm", "methods"), ("isolas", "harmonics"), ("isolas", "amplitudes")])
def test_an_empty_list_is_refused_by_name(section, key, tmp_path, capsys):
    """`[hbm] methods = []` was accepted: the hbm stage then had no output and a run reported
    it "up to date" having computed no NFRC (the validation stage too)."""
    scene = tmp_path / "s.toml"
    scene.write_text(f"[{section}]\n{key} = []\n")
    out = tmp_path / "out"
    line = _refused(["run", str(scene), "--out", str(out), "--until", "mesh"], out, capsys)
    assert line == f"bladerub: error: [{section}] {key} must list at least one value, got []"
    line = _refused(["run", str(COARSE), "--out", str(out), "--until", "mesh", "--set", f"{section}.{key}=[]"],
                    out, capsys)
    assert line == (f"bladerub: error: [{section}] {key} must list at least one value, got [] "
                    f"(command line: --set {section}.{key}=[])")


def test_no_seeds_around_the_primary_is_an_empty_list(tmp_path, capsys):
    """[isolas] primary_amplitudes = [] leaves that family of seeds out; a value that is no
    amplitude is refused by name."""
    assert parse_scene("[isolas]\nprimary_amplitudes = []\n", tmp_path / "s.toml").isolas.primary_amplitudes == ()
    assert parse_scene("", tmp_path / "s.toml", ["isolas.primary_amplitudes=[]"]).isolas.primary_amplitudes == ()
    out = tmp_path / "out"
    line = _refused(["run", str(COARSE), "--out", str(out), "--until", "mesh", "--set",
                     "isolas.primary_amplitudes=[1e-3,0]"], out, capsys)
    assert line == ("bladerub: error: [isolas] primary_amplitudes must be > 0, got [0.001, 0.0] "
                    "(command line: --set isolas.primary_amplitudes=[1e-3,0])")


@pytest.mark.parametrize("text, owner", [("n_harmonics = 20\n[hbm]\nn_time = 1024\n", "hbm"),
                                         ("E = 110e9\n", "material")])
def test_a_key_above_every_section_is_called_a_key_and_its_section_named(text, owner, tmp_path, capsys):
    """A key written before any [section] header was reported as `unknown section [E]`."""
    scene = tmp_path / "s.toml"
    scene.write_text(text)
    key = text.split(" ")[0]
    out = tmp_path / "out"
    line = _refused(["run", str(scene), "--out", str(out), "--until", "mesh"], out, capsys)
    assert line.startswith(f"bladerub: error: unknown top-level key '{key}' in {scene} (a key of [{owner}]: "
                           "write it below that section's header)"), line
    assert "unknown section" not in line


@pytest.mark.parametrize("item, message", [
    ("render.hbm_omega=abc", "[render] hbm_omega must be a number, got 'abc'"),
    ("isolas.workers=2.5", "[isolas] workers must be an integer, got 2.5"),
    ("isolas.omega_min=true", "[isolas] omega_min must be a number, got True"),
    ("blade.contact_nodes=7,a", "[blade] contact_nodes must be an integer, got 'a'"),
])
def test_an_optional_key_of_the_wrong_type_says_what_it_takes(item, message, tmp_path, capsys):
    """Optional keys (float | None, ...) said only `[render] hbm_omega: 'abc' is not a valid
    value`, without the type the key takes or the list item that is wrong."""
    out = tmp_path / "out"
    line = _refused(["run", str(COARSE), "--out", str(out), "--until", "mesh", "--set", item], out, capsys)
    assert line == f"bladerub: error: {message} (command line: --set {item})"


@pytest.mark.parametrize("key", ["geometry", "mesh"])
def test_an_optional_text_key_takes_the_command_lines_text_as_it_is(key, tmp_path):
    """`--set blade.geometry=2024` (a file named 2024) was read as the integer 2024 and
    refused (`[blade] geometry: 2024 is not a valid value`): text needs no quotes."""
    sets = [f"blade.{key}=2024"] + (["blade.units=m"] if key == "mesh" else [])
    scene = parse_scene("", tmp_path / "s.toml", sets)
    assert getattr(scene.blade, key) == "2024"


@pytest.mark.parametrize("section, key, owner", [("hbm", "dt", "ti] and [validation"), ("hbm", "n_revolutions", "ti"),
                                                 ("contact", "penetration", "casing"), ("fem", "E", "material")])
def test_a_key_in_the_wrong_section_names_its_section(section, key, owner, tmp_path, capsys):
    """A known key written in another section was only an `unknown key 'dt' in [hbm]`, with
    the list of [hbm]'s keys: the line now says where it belongs, in a file and with --set."""
    scene = tmp_path / "s.toml"
    scene.write_text(f"[{section}]\n{key} = 1\n")
    out = tmp_path / "out"
    line = _refused(["run", str(scene), "--out", str(out), "--until", "mesh"], out, capsys)
    assert line.startswith(f"bladerub: error: unknown key '{key}' in [{section}] (a key of [{owner}], "
                           f"not of [{section}]); known keys: "), line
    line = _refused(["run", str(COARSE), "--out", str(out), "--until", "mesh", "--set", f"{section}.{key}=1"],
                    out, capsys)
    assert line.startswith(f"bladerub: error: --set '{section}.{key}=1': unknown key '{key}' in [{section}] "
                           f"(a key of [{owner}], not of [{section}]); known keys: "), line
