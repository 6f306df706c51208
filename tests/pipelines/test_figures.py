"""Each result figure is a non-blank PNG of the documented pixel size."""
from __future__ import annotations

import numpy as np
import pytest
from matplotlib.image import imread

from pipelines import figures

SIZE = (round(figures.FIGSIZE[1] * figures.DPI), round(figures.FIGSIZE[0] * figures.DPI))  # rows, cols
#: the amplitude-against-speed figures, their legend right of the axes
WIDE = (round(figures.WIDE_FIGSIZE[1] * figures.DPI), round(figures.WIDE_FIGSIZE[0] * figures.DPI))


def _check(path, wide: bool = False):
    img = imread(path)[..., :3]
    assert img.shape[:2] == (WIDE if wide else SIZE)
    assert img.std() > 0.02  # lines and text, not a blank page
    return img


def _on_save(monkeypatch, look) -> None:
    """look(fig) on every figure saved from now on, just before it is saved."""
    save = figures._save

    def keep(fig, path):
        look(fig)
        return save(fig, path)

    monkeypatch.setattr(figures, "_save", keep)


def _legends(monkeypatch) -> list:
    """The legend texts of every figure saved from now on, one list per figure, in order."""
    legends = []
    _on_save(monkeypatch, lambda fig: legends.append([t.get_text() for t in fig.axes[0].get_legend().get_texts()]))
    return legends


def duffing_like(omega, peak, width, height):
    """A resonance-shaped amplitude curve, m."""
    return height / np.sqrt(1.0 + ((omega - peak) / width) ** 2)


@pytest.fixture
def sweep():
    rng = np.random.default_rng(1)
    omega = np.linspace(420.0, 1980.0, 60)
    amp = duffing_like(omega, 1500.0, 40.0, 2e-3) * (1 + 0.2 * rng.random(60))
    return omega, amp, np.arange(60) % 4


def test_nfrc_draws_lines_and_ti_markers(tmp_path, sweep):
    omega = np.linspace(400.0, 2000.0, 400)
    ok = np.ones(400, bool)
    ok[200:210] = False
    curves = {"DLFT-HBM": (omega, duffing_like(omega, 1500.0, 50.0, 2.2e-3), ok),
              "RL-HBM": (omega, duffing_like(omega, 1510.0, 50.0, 2.1e-3), None),
              "RL-HBM isolas": (omega[:50] + 1000.0, np.full(50, 1e-3))}
    bare = _check(figures.plot_nfrc(curves, tmp_path / "bare.png"), wide=True)
    with_ti = _check(figures.plot_nfrc(curves, tmp_path / "nfrc.png", ti_points=sweep), wide=True)
    assert np.abs(with_ti - bare).max(axis=2).__gt__(0.2).sum() > 200  # the markers are there


def test_ti_sweep(tmp_path, sweep):
    _check(figures.plot_ti_sweep(*sweep, tmp_path / "sub" / "ti.png"), wide=True)


def test_ti_sweep_rings_the_flagged_speeds(tmp_path, sweep):
    """Flagged points get a ring and a legend entry; no flag draws the plain figure; flags
    that do not match the speeds are refused, naming both counts."""
    bare = _check(figures.plot_ti_sweep(*sweep, tmp_path / "bare.png"), wide=True)
    none = _check(figures.plot_ti_sweep(*sweep, tmp_path / "none.png", flagged=np.zeros(60, bool)), wide=True)
    assert np.array_equal(bare, none)
    flags = np.zeros(60, bool)
    flags[::6] = True
    ringed = _check(figures.plot_ti_sweep(*sweep, tmp_path / "ringed.png", flagged=flags), wide=True)
    changed = np.abs(ringed - bare).max(axis=2) > 0.2
    assert changed.sum() > 10 * 20  # ten rings of ~20 dark pixels at least, and the legend's entry
    with pytest.raises(ValueError, match="59 flags for 60 speeds"):
        figures.plot_ti_sweep(*sweep, tmp_path / "bad.png", flagged=flags[1:])


@pytest.mark.parametrize("draw", ["nfrc", "solution_set"])
def test_the_hbm_figures_ring_the_flagged_ti_points(tmp_path, sweep, monkeypatch, draw):
    """ti_points may carry a fourth array, the flags: those points are ringed and the legend
    names them with flagged_label; all flags False draws the figure of the three arrays."""
    plot = getattr(figures, f"plot_{draw}")
    legends = _legends(monkeypatch)
    flags = np.zeros(60, bool)
    bare = _check(plot({}, tmp_path / "bare.png", ti_points=sweep), wide=True)
    none = _check(plot({}, tmp_path / "none.png", ti_points=(*sweep, flags)), wide=True)
    flags[::6] = True
    ringed = _check(plot({}, tmp_path / "ringed.png", ti_points=(*sweep, flags), flagged_label="TI: suspect"), wide=True)
    assert np.array_equal(bare, none)
    assert (np.abs(ringed - bare).max(axis=2) > 0.2).sum() > 10 * 10
    assert "TI: suspect" in legends[2] and "TI: suspect" not in legends[0]


def test_fig_8_tells_a_flagged_ti_point_from_a_fold(tmp_path, sweep, monkeypatch):
    """Fig. 8 marks folds with a small open black circle; a flagged TI point's ring is dashed
    and at least twice as wide, in the figure and in the legend (a solid ring of the TI
    markers' 3.2 times area was a fold's size there)."""
    seen = {}

    def look(fig):
        legend = fig.axes[0].get_legend()
        seen.update(zip([t.get_text() for t in legend.get_texts()], legend.legend_handles
                        if hasattr(legend, "legend_handles") else legend.legendHandles))
        seen["fold in axes"] = [ln for ln in fig.axes[0].get_lines() if ln.get_marker() == "o"]
        seen["rings in axes"] = [c for c in fig.axes[0].collections if len(c.get_offsets()) == 10]

    _on_save(monkeypatch, look)
    omega = np.linspace(400.0, 2000.0, 400)
    amp = duffing_like(omega, 1500.0, 50.0, 2.2e-3)
    flags = np.zeros(60, bool)
    flags[::6] = True
    lines = [("primary", omega, amp, np.ones(400, bool), omega < 1500.0)]
    figures.plot_solution_set({"DLFT": (lines, [("fold", 1500.0, 2.2e-3)])}, tmp_path / "s.png",
                              ti_points=(*sweep, flags), flagged_label="TI: suspect")
    fold_ms = seen["fold in axes"][0].get_markersize()  # points across
    (rings,) = seen["rings in axes"]
    assert np.sqrt(rings.get_sizes()).min() >= 2.0 * fold_ms  # sizes: points squared
    dash = rings.get_linestyle()[0][1]
    assert dash is not None and len(dash) >= 2  # dashed, not solid
    handle = seen["TI: suspect"]
    assert handle.get_linestyle()[0][1] is not None  # the legend shows the dashed ring too


def _ink(path):
    """Pixels that are not background (white or the light grid)."""
    img = imread(path)[..., :3]
    assert img.std() > 0.02
    return int((img.min(axis=2) < 0.6).sum())


def test_content_draws_a_loop_as_a_loop(tmp_path):
    """An isola is a closed curve in (Omega, contribution) too: drawn in its points' order its
    inside stays blank; drawn by increasing Omega (the points reordered), the upper and lower
    halves interleave into a hatched band."""
    s = np.linspace(0.0, 2 * np.pi, 400)
    omega = 1000.0 + 50.0 * np.cos(s)
    c = np.zeros((400, 6))
    c[:, 0] = 0.55 + 0.3 * np.sin(s)
    c[:, 1] = 1.0 - c[:, 0]
    loop = _ink(figures.plot_content({"loop": (omega, c, 1)}, tmp_path / "loop.png"))
    order = np.argsort(omega)
    hatched = _ink(figures.plot_content({"loop": (omega[order], c[order], 1)}, tmp_path / "hatched.png"))
    assert hatched > 3 * loop


def test_content_many_branches_one_panel_each_and_crossings(tmp_path):
    """Eleven branches: no layout warning (the legend of every line of every branch once
    squeezed the axes to nothing), the eight longest drawn; the crossing 4 Omega = omega_1
    inside a branch's span is marked."""
    import warnings

    rng = np.random.default_rng(3)
    curves = {}
    for b in range(11):
        n = 30 + 10 * b
        omega = np.linspace(500.0 + 50 * b, 560.0 + 50 * b, n)
        h = np.abs(rng.normal(size=(n, 21))) * 1e-4
        h[:, 4] += 1e-3
        curves[f"branch {b}"] = (omega, h, 1)
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        bare = imread(figures.plot_content(curves, tmp_path / "h.png", kind="harmonic"))[..., :3]
        w1 = 4.0 * 1030.0  # 4 Omega = omega_1 at 1030 rad/s: inside branch 10's span (1000-1060)
        marked = imread(figures.plot_content(curves, tmp_path / "hm.png", kind="harmonic",
                                             mode_frequencies=[w1, 1e9]))[..., :3]
        modal = figures.plot_content({k: (w, np.abs(h[:, :8]) / np.abs(h[:, :8]).sum(1, keepdims=True), 1)
                                      for k, (w, h, _) in curves.items()}, tmp_path / "m.png")
    assert bare.shape[0] > round(figures.FIGSIZE[1] * figures.DPI)  # four rows of panels
    assert np.abs(marked - bare).max(axis=2).__gt__(0.2).sum() > 100
    assert _ink(modal) > 0


def test_sweep_of_one_speed(tmp_path):
    """A sweep of one speed ([ti] omega_min = omega_max) draws without a singular-limits warning."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        _check(figures.plot_ti_sweep([1110.0], [1e-3], [0], tmp_path / "one.png", omega_range=(1110.0, 1110.0)), wide=True)


def test_content_draws_the_dominant_harmonic(tmp_path):
    """A branch carried by an odd harmonic (a 3 Omega = omega_1 isola) shows it beside the
    even ones of the paper's Fig. 12: its colour (the third of matplotlib's cycle) is on the
    picture."""
    import matplotlib

    red = np.array(matplotlib.colors.to_rgb(matplotlib.rcParams["axes.prop_cycle"].by_key()["color"][3]))
    omega = np.linspace(950.0, 975.0, 60)
    c = np.full((60, 11), 1e-6)
    c[:, 2] = 2e-4
    c[:, 3] = 3e-4 * (1.5 + np.sin(omega / 3.0))
    img = imread(figures.plot_content({"b": (omega, c, 1)}, tmp_path / "b.png", kind="harmonic"))[..., :3]
    assert (np.abs(img - red).max(axis=2) < 0.08).sum() > 200


def test_content_leaves_out_a_branch_without_any_converged_point(tmp_path):
    """A branch whose contributions are all NaN (none of its points converged) is left out:
    the figure of it and a drawable branch is the figure of the drawable branch alone."""
    import warnings

    omega = np.linspace(950.0, 975.0, 60)
    c = np.full((60, 11), 1e-6)
    c[:, 2] = 2e-4 * (1.5 + np.sin(omega / 3.0))
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        for kind in ("harmonic", "modal"):
            both = imread(figures.plot_content({"b": (omega, c, 1), "none": (omega[:5], np.full((5, 11), np.nan), 1)},
                                               tmp_path / f"{kind}2.png", kind=kind))
            alone = imread(figures.plot_content({"b": (omega, c, 1)}, tmp_path / f"{kind}1.png", kind=kind))
            assert both.shape == alone.shape and np.abs(both - alone).max() < 1e-6


def test_a_figure_replaces_its_file_and_a_failed_one_leaves_the_old(tmp_path, sweep, monkeypatch):
    """Figures are written under a temporary name and renamed: a folder copied with hard
    links keeps its own picture when the copy draws again, and a drawing that fails half-way
    (here a full disk) leaves the previous picture and no temporary file."""
    import errno
    import os

    omega, amp, cls = sweep
    png = figures.plot_ti_sweep(omega, amp, cls, tmp_path / "ti_sweep.png")
    old = png.read_bytes()
    os.link(png, tmp_path / "copy.png")  # `cp -al` of the folder
    figures.plot_ti_sweep(omega, 2.0 * amp, cls, png)
    assert png.read_bytes() != old and (tmp_path / "copy.png").read_bytes() == old

    new = png.read_bytes()
    real = figures.plt.Figure.savefig

    def full_disk(self, fname, **kw):
        real(self, fname, **kw)
        with open(fname, "r+b") as fh:
            fh.truncate(100)
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(fname))

    monkeypatch.setattr(figures.plt.Figure, "savefig", full_disk)
    with pytest.raises(OSError, match="No space left"):
        figures.plot_ti_sweep(omega, 3.0 * amp, cls, png)
    assert png.read_bytes() == new
    assert sorted(p.name for p in tmp_path.iterdir()) == ["copy.png", "ti_sweep.png"]


def test_the_solution_set_names_the_friction_lock_in_its_legend(tmp_path, monkeypatch):
    """A branch of kind "friction lock" gets its own colour per treatment and legend entry."""
    legends = _legends(monkeypatch)
    omega = np.linspace(400.0, 2000.0, 50)
    line = ("friction lock", omega, np.full(50, 1e-3), np.ones(50, bool), None)
    _check(figures.plot_solution_set({"DLFT": ([line], []), "RL": ([line], [])}, tmp_path / "set.png"), wide=True)
    assert {"DLFT friction lock", "RL friction lock"} <= set(legends[0])
    assert len(set(figures.KIND_COLOURS["friction lock"]) - {c for k, v in figures.KIND_COLOURS.items()
                                                              if k != "friction lock" for c in v}) == 2


@pytest.mark.parametrize("draw", ["nfrc", "ti_sweep", "solution_set"])
def test_the_amplitude_figures_keep_their_legend_off_the_data(tmp_path, sweep, monkeypatch, draw):
    """The legend of Figs. 5, 6 and 8 stands right of the axes: inside, it hid the coarse
    scene's primary NFRC (Fig. 8) and ringed sweep points of the default one (Fig. 6)."""
    boxes = []

    def look(fig):
        fig.canvas.draw()
        ax = fig.axes[0]
        boxes.append((ax.get_window_extent(), ax.get_legend().get_window_extent(), fig.bbox))

    _on_save(monkeypatch, look)
    omega = np.linspace(400.0, 2000.0, 200)
    amp = duffing_like(omega, 900.0, 80.0, 2e-3)
    flags = np.zeros(60, bool)
    flags[::6] = True
    if draw == "nfrc":
        figures.plot_nfrc({"DLFT-HBM": (omega, amp, None)}, tmp_path / "nfrc.png", ti_points=(*sweep, flags),
                          flagged_label="TI: friction direction of the prediction\nin \u2265 0.1% of contact steps")
    elif draw == "ti_sweep":
        figures.plot_ti_sweep(*sweep, tmp_path / "ti.png", flagged=flags)
    else:
        line = ("primary", omega, amp, np.ones(200, bool), omega < 1200.0)
        figures.plot_solution_set({"DLFT": ([line], []), "RL": ([line], [])}, tmp_path / "set.png",
                                  ti_points=(*sweep, flags))
    ax, legend, page = boxes[0]
    assert legend.x0 >= ax.x1  # beside the axes, not over them
    assert legend.x1 <= page.x1 + 0.5 and legend.y0 >= page.y0 - 0.5  # and on the page
    assert ax.width > 0.55 * page.width  # the data keep most of the figure


def test_a_long_legend_goes_into_columns_and_stays_on_the_page(tmp_path, monkeypatch):
    """More entries than one column of the page's height holds (forty NFRCs, at 7 pt about
    eleven points a row against the page's 324) are set in columns, none cut off below the
    page."""
    boxes = []

    def look(fig):
        fig.canvas.draw()
        legend = fig.axes[0].get_legend()
        boxes.append((legend.get_window_extent(), fig.axes[0].get_window_extent(), fig.bbox, len(legend.get_texts())))

    _on_save(monkeypatch, look)
    omega = np.linspace(400.0, 2000.0, 60)
    figures.plot_nfrc({f"NFRC {i}": (omega, duffing_like(omega, 400.0 + 40.0 * i, 50.0, 1e-3), None)
                       for i in range(40)}, tmp_path / "nfrc.png")
    legend, ax, page, n = boxes[0]
    assert n == 40
    assert legend.y0 >= page.y0 - 0.5 and legend.x1 <= page.x1 + 0.5 and legend.x0 >= ax.x1


def test_an_nfrc_without_a_converged_point_neither_scales_the_axes_nor_reads_as_a_curve(tmp_path, monkeypatch,
                                                                                     sweep):
    """An NFRC that never started (the coarse scene's at mu = 0.25 did, before the arc length in
    mu among the start strategies) holds one failed point, the 120 mm amplitude of the iterate
    Newton gave up on: its cross stretched Fig. 6's axis to 125 mm and
    pressed the sweep's 2 mm points onto the floor, and its name stood in the legend as a
    curve. Now the axes are the sweep's, the legend says the NFRC has no converged point, and
    Fig. 8 names no branch it does not draw."""
    tops, legends = [], []
    _on_save(monkeypatch, lambda fig: (tops.append(fig.axes[0].get_ylim()[1]),
                                       legends.append([t.get_text() for t in fig.axes[0].get_legend().get_texts()])))
    failed = (np.array([2000.0]), np.array([0.120]), np.array([False]))
    _check(figures.plot_nfrc({"DLFT-HBM": failed}, tmp_path / "nfrc.png", ti_points=sweep), wide=True)
    assert 2.4 < tops[0] < 3.0  # mm: the sweep's largest, 2.4 mm, and a margin
    assert legends[0][:2] == ["DLFT-HBM (no converged point)", "not converged"]
    omega = np.linspace(400.0, 2000.0, 50)
    ok = np.ones(50, bool)
    ok[-1] = False  # a branch ending in a failure: its converged points set the axes
    _check(figures.plot_nfrc({"RL-HBM": (omega, np.r_[np.full(49, 1e-3), 0.5], ok)}, tmp_path / "end.png"), wide=True)
    assert 1.0 < tops[1] < 1.2 and legends[1] == ["RL-HBM", "not converged"]
    isola = (omega, np.full(50, 1e-3), ok, None)
    _check(figures.plot_solution_set({"DLFT": ([("primary",) + failed + (None,), ("isola",) + isola], [])},
                                     tmp_path / "set.png"), wide=True)
    assert "DLFT primary" not in legends[2] and "DLFT isola" in legends[2]
