"""The isolas stage's second search, in the basis of Omega / 2, seeded from the sweep's
period-doubled orbits, end to end on the coarse ROM.

Scene: the coarse blade; [hbm] DLFT only at the scene's resolution (N_h = 40: the doubled
search then has 80 harmonics of Omega / 2; with 10 the seed's Newton moves 40 % or fails),
Omega in [1080, 1140] rad/s; [ti] one speed, 1108 rad/s, with the default step and 200
revolutions, where time integration from rest ends on an orbit of 4 casing periods (omega =
Omega / 2, tests/hbm/test_period_doubled_from_ti.py); [isolas] no modal seeds and 40
points per half branch. The search in the basis of Omega has no seed (the one sweep point
does not fit in a revolution); the doubled one continues the point's orbit into a branch of
subharmonic 2 that carries the Omega / 2 harmonics and time integration's amplitude.
"""
import h5py
import numpy as np
import pytest

from coarse_runs import ARTIFACTS
from pipelines.cli import main
from pipelines.stages.isolas import read_isolas
from pipelines.stages.ti import read_sweep
from support import coarse_text

SECTIONS = """[hbm]
methods = ["dlft"]
omega_min = 1080.0
omega_max = 1140.0

[ti]
omega_min = 1108.0
omega_max = 1108.0
n_omega = 1

[isolas]
n_modes = 0
max_points = 40

"""


@pytest.fixture(scope="module")
def searched(coarse_run, tmp_path_factory):
    out = tmp_path_factory.mktemp("isolas_pd")
    for name in ARTIFACTS[:3]:  # mesh, fem, rom: read only
        (out / name).symlink_to((coarse_run[1] / name).resolve())
    text = coarse_text()
    scene = out / "scene.toml"
    scene.write_text(text[: text.index("[hbm]")] + SECTIONS + text[text.index("[render]"):])
    assert main(["run", str(scene), "--out", str(out), "--until", "isolas", "--quiet"]) == 0
    return out


def test_the_sweep_point_seeds_one_period_doubled_branch(searched):
    out = searched
    sweep = read_sweep(out)
    assert sweep.period.tolist() == [4]
    (branch,) = read_isolas(out / "isolas.h5")["dlft"]
    assert branch.subharmonic == 2 and branch.kind in ("bifurcated", "isola", "detached")
    with h5py.File(out / "isolas.h5") as h5:
        s = h5["dlft/seeds"]
        assert [o.decode() for o in s["origin"][()]] == ["ti class subharmonic(omega<Omega) period 4 Omega=1108"]
        assert s["converged"][()].tolist() == [True] and s["branch"][()].tolist() == [0]
        assert h5["dlft"].attrs["n_branches"] == 1
    assert not (out / "isolas.partial.h5").exists()
    # at the seed's speed: the Omega / 2 harmonics (odd rows of the basis of Omega / 2) carry
    # about half the energy, as in time integration (0.43 at the seed)
    ok = branch.converged
    i = int(np.argmin(np.abs(branch.omega[ok] - 1108.0)))
    h = branch.harmonics[ok][i][:, 0]  # LE radial, (2 N_h + 1,)
    n_h = (len(h) - 1) // 2
    odd = sum(h[2 * k - 1] ** 2 + h[2 * k] ** 2 for k in range(1, n_h + 1, 2))
    assert odd / np.sum(h[1:] ** 2) > 0.3
    assert branch.le_amplitude[ok][i] == pytest.approx(sweep.amplitude[0], rel=0.05)
    assert len(branch.omega) > 40  # both halves (40 points at most each) are in it


def test_the_two_searches_of_a_treatment_are_written_as_one():
    """_merged numbers the second search's branches after the first's, and gives a seed of
    the second that lies on an embedded branch of the first (known branch 1 + k) that
    branch's number, a duplicate as its representative, one on the primary (known 0) -2.
    Every branch's seeds and start are indices into the merged seeds: the branch's seeds are
    exactly those whose seed_branch is its number."""
    from types import SimpleNamespace as NS

    from hbm.isolas.search import FoundBranch
    from pipelines.stages.isolas import _merged

    def found(name, start, seeds):
        return FoundBranch(np.zeros(1), np.zeros((1, 1)), np.ones(1, bool), name, False, "", start, seeds)

    first = NS(seeds=("a", "b", "c"), branches=(found("A0", 0, (0,)), found("A1", 1, ())),
               seed_branch=np.array([0, -2, -1]),
               corrections=NS(converged=np.array([True, True, False]), on_known=np.array([-1, 0, -1]),
                              same_as=np.array([-1, -1, -1])))
    second = NS(seeds=("d", "e", "f", "g"), branches=(found("B0", 0, (0,)),), seed_branch=np.array([0, -2, -2, -2]),
                corrections=NS(converged=np.array([True, True, True, True]), on_known=np.array([-1, 2, -1, 0]),
                               same_as=np.array([-1, -1, 1, -1])))
    seeds, converged, seed_branch, branches = _merged([(first, NS(nu=1)), (second, NS(nu=2))])
    assert seeds == ["a", "b", "c", "d", "e", "f", "g"]
    assert converged.tolist() == [True, True, False, True, True, True, True]
    assert seed_branch.tolist() == [0, -2, -1, 2, 1, 1, -2]
    assert [(fb.kind, nu) for fb, nu in branches] == [("A0", 1), ("A1", 1), ("B0", 2)]
    for k, (fb, _) in enumerate(branches):
        assert list(fb.seeds) == np.flatnonzero(seed_branch == k).tolist()
    assert [fb.start for fb, _ in branches] == [0, 1, 3]
