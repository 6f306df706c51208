"""The legend entry of the periodicity class NONE names the sweep's own bound on the
subharmonic order: a point is "no periodicity" when no period up to nu = Omega / omega =
`[ti] max_order` repeats, so with max_order = 15 the legend must read "ω < Ω/15", not the
default's "Ω/10". The expected texts are written out by hand."""
import numpy as np
import pytest

from hbm.options import TimeIntegrationOptions
from hbm.ti.periodicity import PeriodClass
from pipelines import figures

OMEGA = np.array([500.0, 700.0, 900.0])
AMPLITUDE = np.array([1e-4, 2e-4, 3e-4])
CLASSES = np.array([PeriodClass.CASING, PeriodClass.SUBHARMONIC, PeriodClass.NONE])


def _legend(monkeypatch, draw):
    got = {}
    save = figures._save

    def keep(fig, path):
        got["legend"] = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
        return save(fig, path)

    monkeypatch.setattr(figures, "_save", keep)
    draw()
    return got["legend"]


def _draws(tmp_path, **kw):
    ti = (OMEGA, AMPLITUDE, CLASSES)
    return {
        "ti_sweep": lambda: figures.plot_ti_sweep(*ti, tmp_path / "ti.png", **kw),
        "nfrc": lambda: figures.plot_nfrc({}, tmp_path / "nfrc.png", ti_points=ti, **kw),
        "solution_set": lambda: figures.plot_solution_set({}, tmp_path / "set.png", ti_points=ti, **kw),
    }


@pytest.mark.parametrize("figure", ["ti_sweep", "nfrc", "solution_set"])
def test_no_periodicity_label_names_the_sweeps_max_order(monkeypatch, tmp_path, figure):
    options = TimeIntegrationOptions(max_order=15.0)
    legend = _legend(monkeypatch, _draws(tmp_path, max_order=options.max_order)[figure])
    none = [t for t in legend if "no periodicity" in t]
    assert none and none[0].endswith("no periodicity or \u03c9 < \u03a9/15"), legend
    assert not any("/10" in t for t in legend), legend


def test_no_periodicity_label_defaults_to_the_options_default(monkeypatch, tmp_path):
    legend = _legend(monkeypatch, _draws(tmp_path)["ti_sweep"])
    assert "no periodicity or \u03c9 < \u03a9/10" in legend, legend
