"""Fig. 12 (plot_content, kind "harmonic"): every harmonic drawn has its own colour, so that the
legend tells which line is which. A branch carried by k = 12 beside the paper's k = 2, 4, ...
once drew k = 12 in k = 2's colour (the colour cycle taken modulo 10): two legend entries of
one colour. Here each line's colour must name one legend entry "k = K", and the line must be
1e3 |c_K| (mm) of the column K written into the input."""
import numpy as np

from pipelines import figures


def _capture(monkeypatch):
    got = {}
    save = figures._save

    def keep(fig, path):
        got["lines"] = [(ln.get_color(), np.asarray(ln.get_xdata(), float), np.asarray(ln.get_ydata(), float))
                        for ax in fig.axes for ln in ax.get_lines()]
        leg = fig.legends[0]
        got["legend"] = [(t.get_text(), h.get_color()) for t, h in zip(leg.get_texts(), leg.legend_handles)]
        return save(fig, path)

    monkeypatch.setattr(figures, "_save", keep)
    return got


def test_each_drawn_harmonic_has_its_own_colour(monkeypatch, tmp_path):
    got = _capture(monkeypatch)
    omega = np.linspace(900.0, 1000.0, 40)
    c = np.zeros((40, 21))
    levels = {2: 1e-4, 4: 2e-4, 6: 5e-5, 12: 6e-4}  # k = 12 dominant: drawn beside 2, 4, 6
    for k, a in levels.items():
        c[:, k] = a * (1.0 + 0.1 * np.sin(omega / 7.0 + k))
    figures.plot_content({"isola": (omega, c, 1)}, tmp_path / "h.png", kind="harmonic")
    legend = dict(got["legend"])
    assert sorted(legend) == ["k = 12", "k = 2", "k = 4", "k = 6"]
    by_colour = {}
    for text, colour in got["legend"]:
        by_colour.setdefault(colour, []).append(text)
    assert all(len(v) == 1 for v in by_colour.values()), by_colour  # one harmonic per colour
    data = [ln for ln in got["lines"] if len(ln[1]) == len(omega)]
    assert len(data) == 4
    for colour, x, y in data:
        k = int(by_colour[colour][0].split("=")[1])
        np.testing.assert_array_equal(x, omega)
        np.testing.assert_allclose(y, 1e3 * c[:, k], rtol=1e-12)


def test_a_point_not_converged_is_not_drawn_in_the_content(monkeypatch, tmp_path):
    """A branch's point that did not converge (the failed last step a continuation keeps, with
    finite unknowns, so finite contributions) is given with the branch's converged flags: the
    line breaks there instead of joining the point to the branch."""
    got = _capture(monkeypatch)
    omega = np.linspace(900.0, 1000.0, 11)
    c = np.zeros((11, 11))
    c[:, 4] = 2e-4
    c[10, 4] = 9e-4  # the unconverged last point, far off the branch
    conv = np.r_[np.ones(10, bool), False]
    for kind, cc in (("harmonic", c), ("modal", c / np.maximum(c.sum(1, keepdims=True), 1e-30))):
        figures.plot_content({"isola": (omega, cc, 1, conv)}, tmp_path / f"{kind}.png", kind=kind)
        data = [y for _, x, y in got["lines"] if len(x) == len(omega)]
        assert data
        for y in data:
            assert np.isnan(y[10]) and np.isfinite(y[:10]).all()
