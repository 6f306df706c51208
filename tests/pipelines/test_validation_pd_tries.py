"""The validation stage's period-doubling tries go on to the NFRC's other doublings when time
integration leaves the first one's point. On the coarse rotor 67 scene (mu = 0.15, past its
friction lock) both treatments' first doublings lead into the lock, and without stored
stability or a doubled orbit in the sweep nothing else was tried. The rules, with hand-set
doublings, stable flags and marches: the doublings where a stable stretch begins or ends
come next, the longest stretch first, the first try's own doubling and those inside
unchanged stability left out; an NFRC stored without stability has it computed for them, and
only once the first try's march has left."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

import hbm.harmonic.nfrc as nfrc_module
import hbm.stability.selection as selection
import pipelines.stages.validation as stage
from hbm.stability.bifurcation import PERIOD_DOUBLING
from hbm.stability.selection import DoubledBranch
from pipelines.stages.validation import ValidationPoint

N = 40
#: stable on 4-5 (a stretch of 2 beginning at the first try's doubling, after 3), 8-9 (2,
#: ending at the doubling after 9), 21-25 (5, beginning after 20); the doubling after 30 lies
#: inside an unstable stretch
STABLE = np.zeros(N, bool)
STABLE[4:6] = True
STABLE[8:10] = True
STABLE[21:26] = True
BRACKETS = [3, 9, 20, 30]


class _Nfrc:
    """What _period_doubling reads of the NFRC's Candidate."""

    def __init__(self, stable):
        self.stable, self.monitor, self._stability, self.computed = stable, ("scales",), None, 0

    def stability(self):
        if self._stability is None:
            self.computed += 1
            self.stable = STABLE.copy()
            self._stability = SimpleNamespace(
                bifurcations=[SimpleNamespace(kind=PERIOD_DOUBLING, index=i) for i in BRACKETS], n_analyses=300)
        return self._stability

    def computed_words(self):
        return "the branch's stability computed here (300 Floquet analyses along it)"


def _doubled(stable: bool = True) -> DoubledBranch:
    return DoubledBranch(True, "continued both ways", omega_bifurcation=1400.0, multiplier=-1.0,
                         omega=1400.0 - 0.01 * np.arange(4), x=np.zeros((4, 3)), le_amplitude=np.full(4, 1e-3),
                         stable=np.full(4, stable), n_unstable=np.full(4, 0 if stable else 1),
                         new_content=np.full(4, 0.2))


@pytest.fixture
def run(monkeypatch, tmp_path):
    """_period_doubling with doublings after BRACKETS (stored, or computed when `stored` is
    False), the first try's march leaving or staying (`first_stays`), every later one staying
    from the `stays_from`-th try on; returns the point, the marches' sources and the NFRC."""
    omega = np.linspace(2000.0, 400.0, N)

    def go(stored: bool, first_stays: bool, stays_from: int = 1, pd_tries: int = 4, brackets=BRACKETS,
           subcritical: bool = False):
        marches = []

        def try_until_kept(ctx, rom, system, kind, method, candidates, tries, update):
            marches.append(candidates[0].where)
            stays = first_stays if len(marches) == 1 else len(marches) > stays_from
            ti = SimpleNamespace(stays=stays, outcome="stays" if stays else "permanent contact",
                                 verdict=lambda: "stays" if stays else "leaves for permanent contact")
            return ValidationPoint("period_doubling", "dlft", True, "chosen", omega=1400.0, ti=ti)

        def located(r_s, omega_, x, amp, conv, brackets=None, n_scan=24, **k):
            # the first try takes the first doubling (of the table, or of a scan): after point 3
            i = 3 if brackets is None or len(brackets) > 1 else int(brackets[0])
            return SimpleNamespace(bifurcation=SimpleNamespace(omega=float(omega[i])), u=np.zeros(3),
                                   omega=float(omega[i]), reason=f"after {i}", index=i, bracket=(i, i + 1),
                                   switch_starts=lambda omega, x: [None])

        monkeypatch.setattr(stage, "_pd_brackets", lambda path: list(brackets) if stored else None)
        monkeypatch.setattr(stage, "read_branch_set", lambda path, method: [])
        monkeypatch.setattr(stage, "_try_until_kept", try_until_kept)
        monkeypatch.setattr(selection, "locate_period_doubling", located)
        monkeypatch.setattr(selection, "continue_doubled_branch",
                            lambda *a, **k: (_doubled(not subcritical), SimpleNamespace()))
        monkeypatch.setattr(nfrc_module, "default_continuation", lambda hbm: None)
        ctx = SimpleNamespace(out=tmp_path, scene=SimpleNamespace(
            validation=SimpleNamespace(pd_tries=pd_tries, n_scan=24, pd_points=80),
            hbm=SimpleNamespace(subharmonic=1), contact=SimpleNamespace(mu=0.15)))
        b = SimpleNamespace(omega=omega, x=np.zeros((N, 3)), converged=np.ones(N, bool))
        nfrc = _Nfrc(STABLE.copy() if stored else None)
        rom, res = SimpleNamespace(friction_lock=None), SimpleNamespace(n_r=3)
        p, _ = stage._period_doubling(ctx, rom, None, "dlft", res, b, {"le_amplitude": np.zeros(N)},
                                      tmp_path / "nfrc_dlft.h5", lambda s: None, nfrc)
        return p, marches, nfrc

    return go


FIRST = "validation.h5 period-doubled branch of dlft, from the NFRC"


def test_the_nfrc_s_other_doublings_follow_longest_stable_stretch_first(run):
    p, marches, _ = run(stored=True, first_stays=False, stays_from=2)
    assert marches == [FIRST, f"{FIRST} (its period doubling after point 20)",
                       f"{FIRST} (its period doubling after point 9)"]
    assert "tried 3" in p.reason and "after point 30" not in p.reason


def test_the_tries_stop_at_the_first_march_that_stays(run):
    p, marches, _ = run(stored=True, first_stays=False, stays_from=1)
    assert marches == [FIRST, f"{FIRST} (its period doubling after point 20)"]
    assert p.ti.stays and "tried 2" in p.reason


def test_pd_tries_bounds_the_other_doublings(run):
    _, marches, _ = run(stored=True, first_stays=False, stays_from=5, pd_tries=2)
    assert marches == [FIRST, f"{FIRST} (its period doubling after point 20)"]


def test_without_stored_stability_it_is_computed_once_for_them(run):
    p, marches, nfrc = run(stored=False, first_stays=False, stays_from=1)
    assert nfrc.computed == 1
    assert marches == [FIRST, f"{FIRST} (its period doubling after point 20)"]


def test_nothing_more_is_computed_when_the_first_march_stays(run):
    p, marches, nfrc = run(stored=False, first_stays=True)
    assert marches == [FIRST] and nfrc.computed == 0 and "tried" not in p.reason


def test_a_subcritical_first_doubling_is_marched_when_the_nfrc_has_no_other(run):
    """The NFRC's other doublings count as a try left, so a first doubled branch without a
    stable point is passed over for them; when there are none it is still marched."""
    p, marches, _ = run(stored=True, first_stays=False, brackets=[3], subcritical=True)
    assert marches == [FIRST] and p.found
