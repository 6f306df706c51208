"""The static friction-lock check (rom.friction_lock) against time integration.

A two-node toy ROM with a written-down compliance G turns slowly past a two-lobe casing:
each lobe indents one node at a time (the nodes are a radian apart, a lobe 0.15 rad wide),
slowly enough (lobe passage 3 ms, toy periods < 0.08 ms, 20 % damping) for the response to
be quasi-static. The two nodes have tangential couplings of opposite signs (G_rtheta = +6
and -6 against G_rr = 4, 1e-8 m/N), so in either sense of rotation friction pushes one
node into the casing and the other away. The time integration knows nothing of G (it
integrates K = G^-1, M, C).

- At a lobe centre the node sits at r = -p, so its multiplier is the static one,
  lam = p / (G_rr + s mu G_rtheta): raised by friction that pushes the node into the
  casing, lowered by friction that pushes it away.
- Above mu_j = G_rr / |G_rtheta| (= 2/3) the check says friction drags node j into the
  casing faster than the normal force pushes it back: the node cannot leave the casing,
  and the time integration shows it locked on it after the lobe has passed (in contact at
  r > 0, where below mu_j it has let go).
"""
import math

import numpy as np
import pytest

from hbm.options import CasingOptions
from hbm.ti.march import Recording, march, modal_system
from rom.friction_lock import friction_lock
from rom.model import modal_damping

G = 1e-8 * np.array([
    [4.0, 6.0, 0.5, 1.0, 0.2, 0.0],
    [6.0, 12.0, 0.0, 0.4, 0.3, 0.0],
    [0.5, 0.0, 5.0, 0.0, 0.0, 0.1],
    [1.0, 0.4, 0.0, 4.0, -6.0, 0.2],
    [0.2, 0.3, 0.0, -6.0, 12.0, 0.0],
    [0.0, 0.0, 0.1, 0.2, 0.0, 6.0],
])  # m/N, local (r, theta, z) of node 0 then node 1
RHO = np.array([0.25, 0.25])
THETA = np.array([0.0, 1.0])
OMEGA = 50.0  # rad/s: the lobe passes a node in ~0.15 / 50 = 3 ms
CASING = CasingOptions()


def _march(s: int, mu: float, node: int, after: float = 0.0):
    """March the toy from rest to `after` s past `node`'s lobe centre; returns
    (lam, N; r, m) of the node there."""
    K = np.linalg.inv(G)
    M = 1e-3 * np.eye(6)  # kg: toy frequencies 1e5-1e6 rad/s
    C, _ = modal_damping(K, M, np.full(6, 0.2))
    system = modal_system(K, M, C, RHO, THETA, rotation=s)
    dt = 0.2 * 2.0 / system.omega.max()
    # casing angle tau + s theta_j at the lobe centre pi / 2 (mod pi)
    t = ((math.pi / 2 - s * THETA[node]) % math.pi) / OMEGA + after
    n = int(round(t / dt))
    rec = Recording(start=n, stride=1, n_samples=1, dofs=np.array([3 * node]), force_nodes=np.array([node]))
    m = march(system, CASING, mu, OMEGA, np.zeros(6), np.zeros(6), dt, n + 1, rec)
    assert m.active_set_failures == 0
    return float(m.normal_force[0, 0]), float(m.displacement[0, 0])


@pytest.mark.parametrize("s", [1, -1])
@pytest.mark.parametrize("node", [0, 1])
def test_lobe_force_is_the_static_one_friction_raises_or_lowers_it(s, node):
    lock = friction_lock(np.linalg.inv(G), 2, s)
    lam0, r0 = _march(s, 0.0, node)
    lam, r = _march(s, 0.3, node)
    assert r0 == pytest.approx(-CASING.penetration, rel=1e-3) and r == pytest.approx(-CASING.penetration, rel=1e-3)
    # quasi-static to 1 %: inertia (1e-3 kg x ~1e2 m/s^2) and damping forces are < 1e-4 of
    # lam; measured agreement ~1e-4
    assert lam0 == pytest.approx(CASING.penetration / lock.compliance_rr[node, node], rel=1e-2)
    assert lam == pytest.approx(CASING.penetration / lock.radial_compliance(0.3)[node, node], rel=1e-2)
    into = s * lock.compliance_rtheta[node, node] < 0  # the check: friction drags the node outwards
    assert (lam > 1.1 * lam0) if into else (lam < 0.9 * lam0)


@pytest.mark.parametrize("s", [1, -1])
@pytest.mark.parametrize("mu", [0.6, 0.7])
def test_node_the_check_calls_locked_stays_on_the_casing(s, mu):
    lock = friction_lock(np.linalg.inv(G), 2, s)
    node = 1 if s == 1 else 0  # the node whose friction drags it outwards
    assert lock.mu_node[node] == pytest.approx(2.0 / 3.0)
    # 3 ms (one lobe width) past the centre the casing is back out at d = 2.1e-4 m
    lam, r = _march(s, mu, node, after=CASING.width / OMEGA)
    if lock.dragged_in(mu)[node]:
        assert lam > 0 and r > 1e-4  # still pressed on the receding casing: locked
    else:
        assert lam == 0 and abs(r) < 1e-6  # released, back at rest


@pytest.mark.parametrize("s", [1, -1])
@pytest.mark.parametrize("mu", [0.6, 0.7])
def test_validation_march_tells_the_lock_apart(s, mu):
    """The validation's march (hbm.ti.validation) from the toy at rest: it leaves that state
    in every case (the lobes indent the nodes); it ends in "permanent contact" of exactly the
    nodes the static check calls dragged in, and only above their mu_j."""
    from hbm.ti.validation import march_from_hbm

    K = np.linalg.inv(G)
    lock = friction_lock(K, 2, s)
    M = 1e-3 * np.eye(6)
    C, _ = modal_damping(K, M, np.full(6, 0.2))
    system = modal_system(K, M, C, RHO, THETA, rotation=s)
    rest = np.zeros((3, 6))
    rest[1, 0] = rest[1, 3] = 1e-9  # a tiny orbit (m): the rest state with a scale to measure against
    ti = march_from_hbm(system, CASING, mu, rest, OMEGA, n_periods=4, dt=0.2 * 2.0 / system.omega.max())
    assert not ti.stays and ti.max_penetration < 1e-12
    dragged = np.flatnonzero(lock.dragged_in(mu))
    assert ti.locked_nodes.tolist() == dragged.tolist()
    if len(dragged):
        assert ti.outcome == "permanent contact"
        # the dragged node's sliding direction has no fixed point within a step (the step's
        # friction reverses it): those steps take the prediction's, and the verdict says so
        assert ti.explicit_direction_steps > 0
        assert ti.verdict() == (f"leaves for permanent contact ({'LE' if dragged[0] == 0 else 'TE'}) (the friction's "
                                f"direction did not settle at {ti.explicit_direction_steps} steps, which took the "
                                "prediction's)")
    else:
        assert ti.outcome == "leaves" and ti.verdict() == "leaves" and ti.explicit_direction_steps == 0
        assert 0 < ti.contact_fraction.max() < 0.5  # each lobe indents, then lets go


def _sweep_row(s: int, mu: float):
    """The toy's sweep row at OMEGA (hbm.ti.sweep.simulate, Carpenter, three revolutions)."""
    from hbm.options import TimeIntegrationOptions
    from hbm.ti.sweep import simulate

    K = np.linalg.inv(G)
    C, _ = modal_damping(K, 1e-3 * np.eye(6), np.full(6, 0.2))
    system = modal_system(K, 1e-3 * np.eye(6), C, RHO, THETA, rotation=s)
    options = TimeIntegrationOptions(dt=0.2 * 2.0 / system.omega.max(), n_revolutions=3, n_keep=1,
                                     samples_per_revolution=16, stop_when_settled=False, scheme="carpenter")
    return simulate(system, CASING, mu, OMEGA, options)


@pytest.mark.parametrize("s", [1, -1])
def test_a_sweep_counts_the_steps_whose_direction_did_not_settle_and_names_them(s):
    """Below every node's lock (mu = 0.3 < 2/3) each contact step's sliding direction settles;
    at mu = 0.8 a node is dragged onto the casing and most of its contact steps fall back to
    the prediction's direction. ti.h5 keeps the count per speed and the run's log names the
    speed with its share of its contact steps (10 to 100 %); a speed resumed from a file
    written before the count reads -1 (unknown), not 0."""
    from hbm.ti.sweep import SpeedResponse, _stack
    from pipelines.stages.ti import FALLBACK_SHARE_WARNING, explicit_direction_warning, fallback_shares

    free, locked = _sweep_row(s, 0.3), _sweep_row(s, 0.8)
    assert free.contact_fraction > 0.05 and free.explicit_direction_steps == 0
    result = _stack([free, locked])
    assert result.explicit_direction_steps.tolist() == [0, locked.explicit_direction_steps]
    assert explicit_direction_warning(_stack([free])) == ""
    line = explicit_direction_warning(result)
    share = locked.explicit_direction_steps / (locked.contact_fraction * 3 * 2 * math.pi / OMEGA / locked.dt)
    assert 0.1 < share <= 1.0
    np.testing.assert_allclose(fallback_shares(result), [0.0, share], rtol=1e-9)
    assert share >= FALLBACK_SHARE_WARNING  # the log calls it a WARNING, not a note
    assert (f"at 1 speed(s); share of a speed's contact steps, largest first: {OMEGA:.0f} rad/s "
            f"{100 * share:.2g} % ({locked.explicit_direction_steps} steps)") in line
    old = SpeedResponse(**{**free.__dict__, "explicit_direction_steps": None})
    assert _stack([free, old]).explicit_direction_steps.tolist() == [0, -1]


def test_the_sweep_figure_rings_the_speed_past_the_lock(monkeypatch, tmp_path):
    """The ti stage's sweep figure rings the speeds its WARNING names: the toy's speed at
    mu = 0.8 (a node dragged onto the casing), not the one at mu = 0.3."""
    from pathlib import Path

    from hbm.ti.sweep import _stack
    from pipelines import figures
    from pipelines.scene import load_scene
    from pipelines.stages import ti as ti_stage
    from pipelines.stages.base import Context

    result = _stack([_sweep_row(1, 0.3), _sweep_row(1, 0.8)])
    seen = {}
    monkeypatch.setattr(ti_stage, "read_sweep", lambda out: result)
    monkeypatch.setattr(figures, "plot_ti_sweep", lambda *a, **kw: seen.update(kw))
    (tmp_path / ti_stage.TI.file).touch()  # read_sweep's stand-in reads nothing
    scene = load_scene(Path(__file__).resolve().parents[2] / "scenes" / "rotor67_coarse.toml", [])
    ti_stage.draw_sweep(Context(scene, tmp_path, None))
    assert np.asarray(seen["flagged"]).tolist() == [False, True]
    assert "0.1%" in seen["flagged_label"]
    assert np.asarray(ti_stage.sweep_points(tmp_path)[3]).tolist() == [False, True]  # the NFRC's and Fig. 8's


def test_the_warning_names_the_largest_share_first_not_the_largest_count():
    """Ten fallback steps among a speed's few contact steps come before a thousand among many."""
    import dataclasses

    from hbm.ti.sweep import _stack
    from pipelines.stages.ti import explicit_direction_warning

    free = _sweep_row(1, 0.3)
    many = dataclasses.replace(free, omega=60.0, contact_fraction=1.0, explicit_direction_steps=1000)
    few = dataclasses.replace(free, omega=70.0, contact_fraction=1e-4, explicit_direction_steps=10)
    line = explicit_direction_warning(_stack([many, free, few]))
    assert "at 2 speed(s)" in line and line.index("70 rad/s") < line.index("60 rad/s")
