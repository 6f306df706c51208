"""The validation stage's period-doubling tries when a switched doubled branch has no stable
point (a subcritical doubling). On the default rotor 67 scene (DLFT, Zen 4 host) the NFRC's
doubling at ~1349 rad/s is subcritical: its doubled branch is unstable at every point and
time integration from its least unstable point went to the stable primary orbit 0.3 % away
(the branch's odd-harmonic content), a march that could confirm nothing. The rules, with
hand-set outcomes for the branch switch, the marches and the isola search's doubled branch:
such a branch is passed over, unmarched, while another try remains; it is marched only when
no try gives a point at all; a branch with a stable point is marched first, as before."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

import hbm.harmonic.nfrc as nfrc_module
import hbm.stability.selection as selection
import pipelines.stages.validation as stage
from hbm.stability.selection import DoubledBranch
from pipelines.stages.validation import ValidationPoint

MU = 0.15


def _doubled(stable: list[bool]) -> DoubledBranch:
    n = len(stable)
    return DoubledBranch(True, "continued both ways", omega_bifurcation=1349.0, multiplier=-1.0,
                         omega=1349.0 - 0.01 * np.arange(n), x=np.zeros((n, 3)), le_amplitude=np.full(n, 1.9e-3),
                         stable=np.array(stable, bool), n_unstable=np.where(stable, 0, 1),
                         new_content=np.full(n, 0.003))


def _point(omega: float, stays: bool, found: bool = True) -> ValidationPoint:
    ti = SimpleNamespace(stays=stays, outcome="stays" if stays else "leaves",
                         verdict=lambda: "stays" if stays else "leaves for another solution (0.32 % from the orbit)")
    return ValidationPoint("period_doubling", "dlft", found, "chosen" if found else "no branch", omega=omega,
                           ti=ti if found else None)


@pytest.fixture
def run(monkeypatch, tmp_path):
    """_period_doubling with the NFRC's doubled branch `nfrc_stable` (per point) and the isola
    search's doubled branch giving `searched` (a ValidationPoint); returns the result and the
    log of marches."""
    marches = []

    def try_until_kept(ctx, rom, system, kind, method, candidates, tries, update):
        marches.append(candidates[0].where)
        return _point(1348.96, stays=False)

    def located(*a, **k):
        bf = SimpleNamespace(omega=1351.2)
        return SimpleNamespace(bifurcation=bf, u=np.zeros(3), omega=1351.2, reason="located", index=4,
                               bracket=(4, 3), switch_starts=lambda omega, x: [None])

    def go(nfrc_stable, searched):
        monkeypatch.setattr(stage, "_pd_brackets", lambda path: [3])
        monkeypatch.setattr(stage, "read_branch_set", lambda path, method: [])
        monkeypatch.setattr(stage, "searched_doubled_branches", lambda found, nu: [SimpleNamespace(name="010")])
        monkeypatch.setattr(stage, "_try_until_kept", try_until_kept)

        def searched_point(ctx, rom, system, method, n_r, where, br, update):
            marches.append(where)
            return searched, DoubledBranch(searched.found, "the search's")

        monkeypatch.setattr(stage, "_searched_point", searched_point)
        monkeypatch.setattr(selection, "locate_period_doubling", located)
        monkeypatch.setattr(selection, "continue_doubled_branch",
                            lambda *a, **k: (_doubled(nfrc_stable), SimpleNamespace()))
        monkeypatch.setattr(nfrc_module, "default_continuation", lambda hbm: None)
        ctx = SimpleNamespace(out=tmp_path, scene=SimpleNamespace(
            validation=SimpleNamespace(pd_tries=2, n_scan=24, pd_points=80),
            hbm=SimpleNamespace(subharmonic=1), contact=SimpleNamespace(mu=MU)))
        b = SimpleNamespace(omega=np.linspace(2000, 400, 5), x=np.zeros((5, 3)), converged=np.ones(5, bool))
        rom, res = SimpleNamespace(friction_lock=None), SimpleNamespace(n_r=3)
        p, branch = stage._period_doubling(ctx, rom, None, "dlft", res, b, {"le_amplitude": np.zeros(5)},
                                           tmp_path / "nfrc_dlft.h5", lambda s: None)
        return p, branch, marches

    return go


def test_an_unstable_doubled_branch_is_passed_over_for_the_next_try(run):
    p, branch, marches = run([False] * 6, _point(1869.8, stays=True))
    assert marches == ["isolas.h5 dlft/branches/010"]  # the NFRC's doubled branch never marched
    assert p.omega == 1869.8 and branch.reason.startswith("the search's")
    assert "the NFRC: PD at 1351.2 rad/s, no stable point on its doubled branch (6 points), not marched" in p.reason


def test_when_the_next_try_leaves_its_march_is_kept_not_the_unstable_branch(run):
    p, branch, marches = run([False] * 6, _point(1869.8, stays=False))
    assert marches == ["isolas.h5 dlft/branches/010"]
    assert p.omega == 1869.8 and "not marched" in p.reason


def test_the_unstable_branch_is_marched_when_no_other_try_gives_a_point(run):
    p, branch, marches = run([False] * 6, _point(float("nan"), stays=False, found=False))
    assert marches == ["isolas.h5 dlft/branches/010", "validation.h5 period-doubled branch of dlft, from the NFRC"]
    assert p.found and p.omega == 1348.96 and branch.omega_bifurcation == 1349.0
    assert "no stable point on its doubled branch, point at 1349.0 rad/s, time integration leaves" in p.reason
    assert "not marched" not in p.reason


def test_a_doubled_branch_with_a_stable_point_is_marched_first(run):
    p, branch, marches = run([False, False, True, True, False, False], _point(1869.8, stays=True))
    assert marches == ["validation.h5 period-doubled branch of dlft, from the NFRC", "isolas.h5 dlft/branches/010"]
    assert p.omega == 1869.8  # the first march left, the second stayed
