"""The validation stage in the pipeline (on the SHORT coarse scene: N_h = 5, Omega in [1900,
2000] rad/s, 20 periods per point): an isola point taken from an isolas.h5 in the isolas
stage's layout, a recorded reason without one, the stage rerun when isolas.h5 appears,
changes or goes and not otherwise, and the figures (Figs. 8 to 12) non-blank PNGs."""
import h5py
import numpy as np
import pytest
from matplotlib.image import imread

from coarse_runs import clone
from pipelines import artifacts as art
from pipelines.branch_store import load_branch
from pipelines.progress import Progress
from pipelines.runner import plan, run_scene
from pipelines.scene import load_scene
from pipelines.stages.rom import read_rom
from pipelines.stages.validation import read_validation


def _records(scene, out, until="validation"):
    progress = Progress(quiet=True)
    run_scene(load_scene(scene), out, progress=progress, until=until)
    return {r.stage: (r.action, r.why) for r in progress.records}


def write_isolas(path, nfrc, lo: int, hi: int, bump: float = 0.0):
    """A small isolas.h5 in the isolas stage's layout: for DLFT one "isola" (points lo..hi-1 of
    the NFRC file `nfrc`, whose unknowns are the same residual's) with dynamical content, and
    one "bifurcated" branch; for RL a "bifurcated" one and a "detached" one (points lo..hi-1
    of nfrc_rl.h5 beside `nfrc`). bump: added to an attribute so that the file's content
    changes."""
    with h5py.File(path, "r") as h5:  # the isolas stage's own file: its provenance keeps it current
        keep = {k: h5.attrs[k] for k in h5.attrs if k != art.CHECKSUMS}
    path.unlink()  # a link into the shared coarse run: replace it, never write through it
    with h5py.File(path, "w") as h5:
        h5.attrs.update(keep)
        for method, kinds in (("dlft", ("isola", "bifurcated")), ("rl", ("bifurcated", "detached"))):
            s = load_branch(nfrc.parent / f"nfrc_{method}.h5")
            b, ex = s.branch, s.extras
            g = h5.create_group(method)
            g.attrs.update(n_seeds=3, n_converged=2, n_distinct=len(kinds), n_branches=len(kinds), cpu_time=1.0 + bump,
                           wall_time=1.0, status="fixture")
            sd = g.create_group("seeds")
            sd["omega"] = np.array([1950.0, 1960.0, 1970.0])
            sd["origin"] = np.array(["mode 1 k 2", "ti", "ti"], dtype=h5py.string_dtype())
            sd["converged"] = np.array([True, True, False])
            sd["branch"] = np.array([0, len(kinds) - 1, -1])
            for n, kind in enumerate(kinds):
                sl = slice(lo, hi) if kind in ("isola", "detached") else slice(0, 4)
                bg = g.create_group(f"branches/{n:03d}")
                m = len(b.omega[sl])
                bg["omega"], bg["x"], bg["converged"] = b.omega[sl], b.x[sl], b.converged[sl]
                bg["le_amplitude"], bg["harmonics"] = ex["le_amplitude"][sl], ex["harmonics"][sl]
                bg["modal_contribution"] = np.tile([0.7, 0.2, 0.1], (m, 1))
                hc = np.zeros((m, 6))
                hc[:, 2], hc[:, 4] = 0.8, 0.2
                bg["harmonic_contribution"] = hc
                bg.attrs.update(kind=kind, closed=kind == "isola", status="closed loop", subharmonic=1,
                                seeds=np.array([n]))
    art.add_checksums(path)


def _check_png(path):
    img = imread(path)[..., :3]
    assert img.std() > 0.02, path  # lines and text, not a blank page
    return img


def _validate(scene_path, out, **kwargs):
    """The validation stage alone on the folder as it is (the fixture isolas.h5 stands in for
    the search's), as benchmarks/bench_validation.py runs it; kwargs: the stage's compute's
    (workers)."""
    from pipelines.runner import expected_inputs, update_figures
    from pipelines.stages import REGISTRY
    from pipelines.stages.base import Context

    scene = load_scene(scene_path)
    expected = expected_inputs(scene, ("validation",))
    stage, ctx = REGISTRY["validation"], Context(scene, out, Progress(quiet=True))
    for o in stage.outputs(scene):
        ctx.inputs[o.file], ctx.hashes[o.file] = expected[o.file]
    stage.compute(ctx, stage.outputs(scene), **kwargs)
    update_figures(scene, out, [stage], Progress(quiet=True))
    return read_validation(out)


@pytest.fixture(scope="module")
def runs(coarse_nfrc, tmp_path_factory):
    """A clone of the SHORT coarse folder run through validation (its own search finds no
    isola), again; the validation stage on a fixture isolas.h5 with an isola; then the scene's
    [isolas] changed and the search run again. Returns (out, [(records, artifact)] for the
    first three, then (records, the runner's plan for the validation stage), then (None, the
    first run's validation again with its treatments one after the other in this process)))."""
    out = tmp_path_factory.mktemp("validation_points")
    scene = clone(coarse_nfrc[1], out)
    done = []

    def run():
        rec = _records(scene, out)
        done.append((rec, read_validation(out)))

    run()
    # the first run's inputs, linked before anything replaces them
    serial_out = tmp_path_factory.mktemp("validation_serial")
    serial_scene = clone(out, serial_out)
    (serial_out / "validation.h5").unlink()
    serial = _validate(serial_scene, serial_out, workers=1)
    run()
    write_isolas(out / "isolas.h5", out / "nfrc_dlft.h5", 3, 12)
    done.append((None, _validate(scene, out)))
    scene.write_text(scene.read_text().replace("amplitudes = [1e-3]", "amplitudes = [2e-3]"))
    # the search again, and what a run would do next at the validation stage (the runner's
    # plan; the stage's own rerun and reuse: above)
    rec = _records(scene, out, until="isolas")
    done.append((rec, plan(load_scene(scene), out, ("validation",))[0]))
    done.append((None, serial))
    return out, done


def test_isola_point_from_isolas_h5_and_reruns_when_the_search_does(runs):
    out, done = runs
    (rec, a), (rec_again, _), (_, b), (rec_changed, next_validation), _ = done
    # the search of the short scene finds no isola: a recorded reason, not an error
    assert rec["validation"][0] == "computed"
    rom = read_rom(out)
    for t in (a.dlft, a.rl):
        assert not t.isola.found and "no branch of kind 'isola' or 'detached'" in t.isola.reason
        p = t.primary
        assert p.found and p.ti is not None and p.ti.n_periods == 20 and p.ti.deviation.shape == (20, 2)
        # where the march went, read back from validation.h5: its last period on the point's
        # harmonics (every dof of the ROM) and the HBM solution through it
        assert p.ti.last_harmonics.shape == (len(p.u) // (3 * rom.n_boundary), rom.n_dof) and p.ti.reached is not None
        assert np.isfinite(p.ti.reached.distance) and (p.ti.outcome == "another solution") == (
            p.ti.reached.converged and p.ti.reached.solution_distance > 1e-3 and p.ti.growth <= 1.5
            and p.ti.deviation[-2:].max() <= 0.6)
        # both treatments compared at the point: its own orbit, the other's by Newton (or why not)
        own, other = getattr(p, t.method), getattr(p, "rl" if t.method == "dlft" else "dlft")
        assert own.source == "the point itself" and own.converged
        assert "Newton" in other.source
        assert np.all(np.isfinite(own.displacement_error)) and np.all(np.isfinite(own.force_error))
        # the RL force compared is that of the RL-HBM equilibrium (Lanczos sigma applied)
        for m, c in ((t.method, own), ("rl" if t.method == "dlft" else "dlft", other)):
            if c.converged:
                assert c.force_filter == ("sigma" if m == "rl" else "none"), (m, c.force_filter)
        # each treatment's own Hill verdict on its orbit is kept beside the march; for the
        # point's own treatment it is that of the analysis that chose the point (reused when
        # the stage made it, computed when the verdict was the branch file's): a stable
        # choice is stable there
        for c in (own, other):
            if c.converged:
                assert c.n_unstable >= 0 and c.multiplier > 0.0
        if p.stable:
            assert own.n_unstable == 0 and own.multiplier < 1.0
        if np.isfinite(p.multiplier):
            assert own.multiplier == pytest.approx(p.multiplier, rel=1e-6)
        # the period doubling: found with its branch, or a reason
        assert t.period_doubling.found == t.pd_branch.found and t.period_doubling.reason
        # the NFRC file holds no stability: when the stage computed it, one flag per point is kept
        n = len(load_branch(out / f"nfrc_{t.method}.h5").branch.omega)
        assert (len(t.nfrc_stable), bool(t.nfrc_stability)) in ((0, False), (n, True)), t.nfrc_stability
    assert a.isolas.endswith("isolas.h5") and a.growth_tol == 1.5 and a.cpu_time > 0
    assert rec_again["validation"][0] == "reused"
    # an isolas.h5 with an isola: the DLFT isola point lies on it
    iso = b.dlft.isola
    assert iso.found and iso.branch == "isolas.h5 dlft/branches/000" and 0 <= iso.index < 9
    omega = load_branch(out / "nfrc_dlft.h5").branch.omega
    assert iso.omega == omega[3 + iso.index] and iso.ti is not None
    # RL has no isola but a "detached" branch, which never meets the primary either: its point
    iso = b.rl.isola
    assert iso.found and iso.branch == "isolas.h5 rl/branches/001" and 0 <= iso.index < 9
    assert iso.omega == load_branch(out / "nfrc_rl.h5").branch.omega[3 + iso.index] and iso.ti is not None
    # the search's inputs change: it reruns, and so does the validation after it
    assert rec_changed["isolas"][0] == "computed"
    assert next_validation.todo and "isolas.h5" in next_validation.why, next_validation.why


def test_treatments_at_once_give_the_validation_of_one_after_the_other(runs):
    """The stage's default (one process per treatment, on two cores) against workers=1 (this
    process, one after the other): the same points, verdicts and differences to round-off
    (one BLAS thread per treatment either way)."""
    _, done = runs
    (_, at_once), (_, serial) = done[0], done[-1]
    n_found = 0
    for method in ("dlft", "rl"):
        t, u = getattr(at_once, method), getattr(serial, method)
        assert t.cpu_time > 0 and u.cpu_time > 0
        for kind in ("primary", "isola", "period_doubling"):
            p, q = getattr(t, kind), getattr(u, kind)
            assert (p.found, p.reason, p.branch, p.index) == (q.found, q.reason, q.branch, q.index), (method, kind)
            if not p.found:
                continue
            n_found += 1
            assert p.omega == q.omega and p.stable == q.stable and p.n_unstable == q.n_unstable
            assert (p.ti is None) == (q.ti is None)
            if p.ti is not None:
                assert p.ti.outcome == q.ti.outcome
                np.testing.assert_allclose(p.ti.deviation, q.ti.deviation, rtol=1e-6, atol=1e-9)
            for m in ("dlft", "rl"):
                c, d = getattr(p, m), getattr(q, m)
                np.testing.assert_allclose(c.displacement_error, d.displacement_error, rtol=1e-6, atol=1e-9)
    assert n_found >= 2  # both primaries at least: the comparison compares marches


def test_figures_are_drawn_from_the_artifacts(runs):
    out, _ = runs
    figs = out / "figures"
    for name in ("solution_set.png", "solution_set_dlft.png", "solution_set_rl.png", "validation_dlft.png",
                 "validation_rl.png", "contact_dlft.png", "contact_rl.png", "isola_modal_content.png",
                 "isola_harmonic_content.png", "content_modal_dlft.png", "content_harmonic_dlft.png",
                 "content_modal_rl.png", "content_harmonic_rl.png"):
        _check_png(figs / name)
    # the overlay holds both treatments' curves: it differs from a single one
    both, one = _check_png(figs / "solution_set.png"), _check_png(figs / "solution_set_dlft.png")
    assert np.abs(both - one).max(axis=2).__gt__(0.2).sum() > 200


def test_content_is_drawn_along_every_branch_of_each_treatment(runs, tmp_path, monkeypatch):
    """Figs. 11 and 12 along any branch: one panel for the NFRC and one for each branch of
    isolas.h5 whatever its kind, each line the stored column it stands for (modal: the
    contribution of modes 1-4 and the sum of the rest; harmonic: |c_k| in mm), points not
    converged left out."""
    import matplotlib.pyplot as plt

    from pipelines import figures
    from pipelines.stages.base import Context
    from pipelines.stages.validation import draw_branch_content

    out, _ = runs
    scene = clone(out, tmp_path / "content")
    folder = scene.parent
    write_isolas(folder / "isolas.h5", folder / "nfrc_dlft.h5", 3, 12)
    drawn = {}

    def keep(fig, path):
        drawn[path.name] = {ax.get_title().split(",")[0]: [np.asarray(ln.get_ydata(), float) for ln in ax.get_lines()
                                                           if ln.get_linestyle() == "-"]
                            for ax in fig.axes if ax.get_lines()}
        plt.close(fig)
        return path

    monkeypatch.setattr(figures, "_save", keep)
    draw_branch_content(Context(load_scene(scene), folder, Progress(quiet=True)))
    assert set(drawn) == {f"content_{k}_{m}.png" for k in ("modal", "harmonic") for m in ("dlft", "rl")}
    assert set(drawn["content_modal_dlft.png"]) == {"DLFT primary", "DLFT isola 000", "DLFT bifurcated 001"}
    assert set(drawn["content_harmonic_rl.png"]) == {"RL primary", "RL bifurcated 000", "RL detached 001"}
    for m in ("dlft", "rl"):
        s = load_branch(folder / f"nfrc_{m}.h5")
        ok = s.branch.converged
        stored = s.extras["modal_contribution"]
        lines = drawn[f"content_modal_{m}.png"][f"{m.upper()} primary"]
        assert len(lines) == 5  # modes 1 to 4, then the rest summed
        for j in range(4):
            np.testing.assert_allclose(lines[j][ok], stored[ok, j], rtol=1e-12)
            assert np.isnan(lines[j][~ok]).all()
        np.testing.assert_allclose(lines[4][ok], stored[ok, 4:].sum(axis=1), rtol=1e-12)
        # the fixture's branches: 0.7, 0.2, 0.1 of modes 1-3; |c_2| = 0.8 m, |c_4| = 0.2 m
        for label, lines in drawn[f"content_modal_{m}.png"].items():
            if "primary" not in label:
                assert [np.nanmax(y) for y in lines[:3]] == pytest.approx([0.7, 0.2, 0.1])
        for label, lines in drawn[f"content_harmonic_{m}.png"].items():
            if "primary" not in label:
                assert sorted(np.nanmax(y) for y in lines)[-2:] == pytest.approx([200.0, 800.0])


def test_the_solution_set_marks_the_ends_of_stable_stretches():
    """Fig. 8 marks the bifurcations where the stable flag changes, not those among orbits
    already unstable (which stay in the files)."""
    from pipelines.stages.validation import _stability_bounds

    stable = np.array([True, True, False, False, False, True])
    table = {"kind": np.array(["period doubling", "Neimark-Sacker", "fold", "branch point"], dtype=object),
             "omega": np.array([1.5, 2.5, 3.5, 4.5]), "le_amplitude": np.array([1e-3, 2e-3, 3e-3, 4e-3]),
             "index": np.array([1, 2, 3, 4])}
    # a table written before the paired column: every kind counts as measured
    assert _stability_bounds(table, stable) == [("period doubling", 1.5, 1e-3, False), ("branch point", 4.5, 4e-3, False)]
    assert len(_stability_bounds(table, None)) == 4  # no stability stored: all of them
    table["paired"] = np.array([True, True, True, False])
    assert _stability_bounds(table, stable) == [("period doubling", 1.5, 1e-3, False), ("branch point", 4.5, 4e-3, True)]
    # today's column: a kind from the parities of the real multipliers is not a guess
    del table["paired"]
    table["kind_from"] = np.array(["crossing", "crossing", "crossing", "parity"], dtype=object)
    assert _stability_bounds(table, stable)[1][3] is False
    table["kind_from"][3] = "guess"
    assert _stability_bounds(table, stable)[1][3] is True


def test_a_guessed_kind_is_drawn_grey(tmp_path):
    """Fig. 8 draws a bifurcation whose kind is a guess (no multiplier paired across the
    circle) in grey, with a legend entry, and a measured one in black."""
    from pipelines.figures import GUESSED, plot_solution_set

    line = ("primary", np.linspace(400, 2000, 50), np.full(50, 1e-3), np.ones(50, bool), np.ones(50, bool))
    grey = float(GUESSED) * 255

    def grey_pixels(guessed: bool) -> int:
        png = plot_solution_set({"DLFT": ([line], [("period doubling", 1200.0, 2e-3, guessed)])},
                                tmp_path / f"s_{guessed}.png")
        img = imread(png)[..., :3].astype(float) * (255 if imread(png).dtype.kind == "f" else 1)
        return int((np.abs(img - grey).max(axis=2) < 8).sum())

    assert grey_pixels(True) > grey_pixels(False) + 20


def test_period_doublings_to_try_end_stable_stretches_longest_first():
    from types import SimpleNamespace

    from pipelines.stages.validation import doubling_candidates

    def branch(name, stable, kinds, index):
        return SimpleNamespace(name=name, stable=np.array(stable, bool),
                               bifurcations={"kind": np.array(kinds, dtype=object), "index": np.array(index)})

    a = branch("000", [0, 1, 1, 0, 0, 0], ["period doubling", "period doubling", "Neimark-Sacker"], [0, 2, 4])
    b = branch("001", [0, 0, 1, 1, 1, 1, 0], ["period doubling", "fold", "period doubling", "period doubling"],
               [1, 5, 5, 3])
    c = SimpleNamespace(name="002", stable=None, bifurcations=None)  # a search without stability
    got = [(br.name, i) for br, i in doubling_candidates([a, b, c])]
    # b's stretch of 4 (both its ends), then a's of 2; the fold, the Neimark-Sacker and the
    # doubling inside b's stretch (3 -> 4, both stable) are not candidates
    assert got == [("001", 1), ("001", 5), ("000", 0), ("000", 2)]


def test_the_guessed_legend_entry_is_no_kind_marker(tmp_path, monkeypatch):
    """A guessed mark keeps its kind's marker in grey, so the legend's "kind guessed" entry
    must not be a marker of its own: a grey circle would read as a guessed fold."""
    import matplotlib.axes

    from pipelines.figures import BIFURCATION_MARKERS, plot_solution_set

    seen = {}
    real = matplotlib.axes.Axes.legend

    def capture(self, *args, handles=None, **kw):
        seen.update({h.get_label(): h for h in handles or []})
        return real(self, *args, handles=handles, **kw)

    monkeypatch.setattr(matplotlib.axes.Axes, "legend", capture)
    line = ("primary", np.linspace(400, 2000, 50), np.full(50, 1e-3), np.ones(50, bool), np.ones(50, bool))
    plot_solution_set({"DLFT": ([line], [("period doubling", 1200.0, 2e-3, True)])}, tmp_path / "g.png")
    guessed = [h for label, h in seen.items() if "guessed" in label]
    assert len(guessed) == 1
    marker = getattr(guessed[0], "get_marker", lambda: None)()
    assert marker not in BIFURCATION_MARKERS.values()
