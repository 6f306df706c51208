"""Fig. 8 (plot_solution_set) segment by segment against the input: every drawn segment joins
two consecutive points of one branch, both converged and finite; a point not converged or a
NaN row is never bridged; a segment whose two end points have the same stability is drawn in
that stability's style, and one where stability changes takes the style of the first of the
two in the branch's order (the convention plot_solution_set states)."""
import numpy as np

from pipelines import figures

STYLE = {"-": "stable", "--": "unstable", ":": "unknown"}


def _segments(monkeypatch, tmp_path, line):
    got = {}
    save = figures._save

    def keep(fig, path):
        got["lines"] = [(ln.get_linestyle(), np.asarray(ln.get_xdata(), float), np.asarray(ln.get_ydata(), float))
                        for ln in fig.axes[0].get_lines() if ln.get_linestyle() in STYLE]
        return save(fig, path)

    monkeypatch.setattr(figures, "_save", keep)
    figures.plot_solution_set({"RL": ([line], [])}, tmp_path / "s.png")
    w = np.asarray(line[1], float)
    segs = []
    for style, x, y in got["lines"]:
        for p in range(len(x) - 1):
            if np.isfinite([x[p], y[p], x[p + 1], y[p + 1]]).all():
                i = int(np.flatnonzero(w == x[p])[0])
                assert w[i + 1] == x[p + 1] and 1e3 * line[2][i + 1] == y[p + 1]  # consecutive points
                segs.append((i, STYLE[style]))
    return segs


def test_segments_match_their_end_points(monkeypatch, tmp_path):
    n = 30
    w = np.linspace(500.0, 800.0, n)
    a = 1e-3 * (1.0 + 0.3 * np.sin(w / 40.0))
    conv = np.ones(n, bool)
    conv[[8, 20]] = False  # 8: inside a stable stretch; 20: where stability changes
    a[14] = np.nan  # a NaN row flagged converged
    stable = np.zeros(n, bool)
    stable[3:12] = True
    stable[19] = True  # a single stable point just before the unconverged 20
    stable[24] = True  # a single stable point between unstable ones
    count = np.where(stable, 0, 1)
    count[[16, 17]] = -1  # no verdict
    segs = _segments(monkeypatch, tmp_path, ("isola", w, a, conv, stable, count))
    state = np.where(stable, "stable", "unstable").astype(object)
    state[count < 0] = "unknown"
    expected = []
    for i in range(n - 1):
        if conv[i] and conv[i + 1] and np.isfinite(a[i]) and np.isfinite(a[i + 1]):
            expected.append((i, state[i]))  # the first point's style, also where it changes
    assert sorted(segs) == expected
    drawn = {i for i, _ in segs}
    assert not drawn & {7, 8, 13, 14, 19, 20}  # nothing bridges 8, 14 (NaN) or 20
    assert (24, "stable") in segs and (23, "unstable") in segs
    assert (15, "unstable") in segs and (16, "unknown") in segs and (17, "unknown") in segs


def test_a_branch_not_converged_with_twice_the_harmonics_is_faded(monkeypatch, tmp_path):
    """The seventh member of a line (isolas.h5's harmonic_check "not converged") draws every
    segment of that branch at TRUNCATED_ALPHA and adds its legend entry; the others stay opaque."""
    got = {}
    save = figures._save

    def keep(fig, path):
        ax = fig.axes[0]
        got["alpha"] = [(ln.get_xdata()[0], ln.get_alpha()) for ln in ax.get_lines() if ln.get_linestyle() in STYLE]
        got["legend"] = [t.get_text() for t in ax.get_legend().get_texts()]
        return save(fig, path)

    monkeypatch.setattr(figures, "_save", keep)
    w = np.linspace(500.0, 600.0, 10)
    a = np.full(10, 1e-3)
    ok, stable = np.ones(10, bool), np.r_[np.ones(5, bool), np.zeros(5, bool)]
    figures.plot_solution_set({"RL": ([("isola", w, a, ok, stable, None, True),
                                       ("primary", w + 200.0, a, ok, stable, None, False)], [])}, tmp_path / "s.png")
    faded = [al for x, al in got["alpha"] if x < 650.0]
    opaque = [al for x, al in got["alpha"] if x >= 650.0]
    assert len(faded) == len(opaque) == 2  # a stable and an unstable run each
    assert all(al == figures.TRUNCATED_ALPHA for al in faded) and all(al in (None, 1.0) for al in opaque)
    assert "faded: not converged with 2 N_h" in got["legend"]
    figures.plot_solution_set({"RL": ([("primary", w, a, ok, stable)], [])}, tmp_path / "t.png")
    assert "faded: not converged with 2 N_h" not in got["legend"]
