"""Fig. 12 (plot_content, kind "harmonic") labels and colours each harmonic by its frequency
k Omega, whatever the branch's basis: on a branch of Omega / 2 (nu = 2) column i of the
contributions oscillates at i Omega / 2, so the paper's k = 2, 4, ..., 10 (multiples of Omega)
are its columns 4, 8, ..., 20. The code once drew columns 2, 4, ..., 10 there (Omega to
5 Omega) under the labels and colours of 2 Omega to 10 Omega of the nu = 1 panels. Each line
is checked against the column it must be (1e3 c[:, nu k], mm), its colour against the legend
entry "k = K" of its frequency, the same in both panels, and the mode crossings k Omega =
omega_j at omega_j / k."""
from fractions import Fraction

import numpy as np

from pipelines import figures


def _capture(monkeypatch):
    got = {}
    save = figures._save

    def keep(fig, path):
        got["panels"] = [[(ln.get_color(), ln.get_linestyle(), np.asarray(ln.get_xdata(), float),
                           np.asarray(ln.get_ydata(), float)) for ln in ax.get_lines()]
                         for ax in fig.axes if ax.get_lines()]
        got["texts"] = [[t.get_text() for t in ax.texts] for ax in fig.axes if ax.get_lines()]
        leg = fig.legends[0]
        got["legend"] = [(t.get_text(), h.get_color()) for t, h in zip(leg.get_texts(), leg.legend_handles)]
        got["legend_title"] = leg.get_title().get_text()
        return save(fig, path)

    monkeypatch.setattr(figures, "_save", keep)
    return got


def _branches():
    omega1 = np.linspace(900.0, 1000.0, 30)
    omega2 = np.linspace(600.0, 700.0, 40)
    c1 = np.zeros((30, 21))
    c2 = np.zeros((40, 41))
    for k, a in {2: 3e-4, 4: 2e-4, 6: 1e-4, 8: 5e-5, 10: 4e-5}.items():
        c1[:, k] = a * (1.0 + 0.1 * np.sin(omega1 / 9.0 + k))
    # nu = 2: every column carries something; the dominant one is column 3, 3 Omega / 2
    c2[:, 1:] = 1e-5 * (1.0 + np.arange(1, 41)[None, :] / 100.0) * (1.0 + 0.05 * np.cos(omega2 / 5.0))[:, None]
    c2[:, 3] = 8e-4
    for i in (4, 8, 12, 16, 20):
        c2[:, i] = 1e-4 * i / 4.0 * (1.0 + 0.1 * np.sin(omega2 / 7.0 + i))
    return {"isola nu1": (omega1, c1, 1), "isola nu2": (omega2, c2, 2)}


def test_harmonics_are_drawn_by_their_frequency_in_a_basis_of_omega_over_2(monkeypatch, tmp_path):
    got = _capture(monkeypatch)
    curves = _branches()
    figures.plot_content(curves, tmp_path / "h.png", kind="harmonic")
    legend = dict(got["legend"])
    assert set(legend) == {"k = 2", "k = 4", "k = 6", "k = 8", "k = 10", "k = 3/2"}
    assert "k\u03a9" in got["legend_title"]  # the legend says what k is
    assert len(set(legend.values())) == len(legend)  # one colour per frequency
    colour_k = {colour: Fraction(text.split("=")[1].strip()) for text, colour in got["legend"]}
    for (label, (omega, c, nu)), lines in zip(curves.items(), got["panels"]):
        data = [ln for ln in lines if ln[1] == "-" and len(ln[2]) == len(omega)]
        ks = sorted(colour_k[colour] for colour, _, _, _ in data)
        want = [Fraction(k) for k in (2, 4, 6, 8, 10)] + ([Fraction(3, 2)] if nu == 2 else [])
        assert ks == sorted(want), (label, ks)
        for colour, _, x, y in data:
            k = colour_k[colour]
            col = k * nu
            assert col.denominator == 1
            np.testing.assert_array_equal(x, omega)
            np.testing.assert_allclose(y, 1e3 * c[:, int(col)], rtol=1e-12, err_msg=f"{label} k = {k}")


def test_mode_crossings_are_at_omega_j_over_k_in_any_basis(monkeypatch, tmp_path):
    got = _capture(monkeypatch)
    curves = _branches()
    w1 = 4.0 * 650.0  # 4 Omega = omega_1 at 650 rad/s (nu = 2 panel); no other k meets a mode in a span
    w2 = 8.0 * 950.0  # 8 Omega = omega_2 at 950 rad/s (nu = 1 panel)
    figures.plot_content(curves, tmp_path / "h.png", kind="harmonic", mode_frequencies=[w1, w2])
    legend = dict(got["legend"])
    marks = [[(ln[0], ln[2][0]) for ln in lines if ln[1] == "--"] for lines in got["panels"]]
    assert marks[0] == [(legend["k = 8"], 950.0)]
    assert marks[1] == [(legend["k = 4"], 650.0)]
    assert "8\u03a9 = \u03c92" in got["texts"][0]
    assert "4\u03a9 = \u03c91" in got["texts"][1]


def test_the_modal_labels_carry_the_mode_frequencies_given(monkeypatch, tmp_path):
    """Fig. 11: column j is mode j + 1 in ascending frequency; given the frequencies, each label
    names its own."""
    got = _capture(monkeypatch)
    omega = np.linspace(900.0, 1000.0, 20)
    c = np.full((20, 6), 1.0 / 6.0)
    freq = np.array([2759.0, 7777.0, 12052.0, 15000.0, 20000.0, 30000.0])
    figures.plot_content({"isola": (omega, c, 1)}, tmp_path / "m.png", kind="modal", mode_frequencies=freq)
    texts = [t for t, _ in got["legend"]]
    assert texts == ["mode 1 (2759 rad/s)", "mode 2 (7777 rad/s)", "mode 3 (12052 rad/s)", "mode 4 (15000 rad/s)",
                     "modes 5 to 6"]
