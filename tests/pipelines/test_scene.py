"""Scene parsing: defaults, overrides, and clear errors for bad input."""
from pathlib import Path

import pytest

from pipelines.scene import SceneError, load_scene, parse_scene

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
