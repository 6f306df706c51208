"""Fig. 8 draws a point whose stability has no verdict (n_unstable -1, stored with stable
False) as unknown (dotted), not as unstable (dashed): a branch stable over its first 20
points, without a verdict over the next 10, unstable (2 multipliers out) over the last 20.
The runs expected are written out by hand (each run reaches one point into the next, so the
curve stays connected)."""
from pathlib import Path

import numpy as np

from pipelines import figures


def _drawn(monkeypatch, tmp_path, line):
    got = {}
    save = figures._save

    def keep(fig, path):
        ax = fig.axes[0]
        got["lines"] = [(ln.get_linestyle(), ln.get_xdata()) for ln in ax.get_lines() if len(ln.get_xdata()) > 1]
        got["legend"] = [t.get_text() for t in ax.get_legend().get_texts()]
        return save(fig, path)

    monkeypatch.setattr(figures, "_save", keep)
    figures.plot_solution_set({"DLFT": ([line], [])}, tmp_path / "s.png")
    return got


def test_a_point_without_a_verdict_is_drawn_unknown_not_unstable(monkeypatch, tmp_path):
    w = np.linspace(400.0, 2000.0, 50)
    stable = np.r_[np.ones(20, bool), np.zeros(30, bool)]
    n_unstable = np.r_[np.zeros(20, int), np.full(10, -1), np.full(20, 2)]
    got = _drawn(monkeypatch, tmp_path, ("primary", w, np.full(50, 1e-3), np.ones(50, bool), stable, n_unstable))
    by_style = {style: x for style, x in got["lines"]}
    assert set(by_style) == {"-", ":", "--"}
    np.testing.assert_array_equal(by_style["-"], w[0:21])
    np.testing.assert_array_equal(by_style[":"], w[20:31])
    np.testing.assert_array_equal(by_style["--"], w[30:50])
    assert {"stable", "unstable", "unknown"} <= set(got["legend"])
    assert Path(tmp_path / "s.png").stat().st_size > 0


def test_without_the_counts_stable_false_is_unstable(monkeypatch, tmp_path):
    # a line of four items (a caller without counts, or a file of an earlier version)
    w = np.linspace(400.0, 2000.0, 10)
    stable = np.r_[np.ones(4, bool), np.zeros(6, bool)]
    got = _drawn(monkeypatch, tmp_path, ("isola", w, np.full(10, 1e-3), np.ones(10, bool), stable))
    assert [s for s, _ in got["lines"]] == ["-", "--"]
