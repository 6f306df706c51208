"""The legend entry of the periodicity class NONE names the sweep's own bound on the
subharmonic order: a point is "no periodicity" when no period up to nu = Omega / omega =
`[ti] max_order` repeats, so with max_order = 15 the legend must read "ω < Ω/15", not the
default's "Ω/10", where the kept window can show such a period twice ([ti] n_keep >= 30), and
"Ω/10" where it cannot (n_keep = 20). The expected texts are written out by hand."""
from pathlib import Path

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


@pytest.mark.parametrize("n_lobes", [2, 3])
@pytest.mark.parametrize("n_keep, max_order", [(20, 15.0), (20, 10.0), (30, 15.0), (7, 10.0), (8, 3.5)])
def test_the_order_named_is_the_one_the_classifier_can_find(n_lobes, n_keep, max_order):
    """With [ti] max_order = 15 and the default n_keep = 20 the sweep's window holds 20 n_l + 1
    sections, so periods beyond 10 revolutions are never seen twice: the legend read "Ω/15"
    where the classifier stops at 10. classified_order must be the largest order a sequence of
    that window with an exact period is called periodic at, and one casing period more is not."""
    from hbm.ti.periodicity import classify_period

    order = TimeIntegrationOptions(n_revolutions=200, n_keep=n_keep, max_order=max_order).classified_order(n_lobes)
    p = round(order * n_lobes)
    n_sec = n_keep * n_lobes + 1
    rng = np.random.default_rng(p)
    for period, found in ((p, True), (p + 1, False)):
        sections = np.resize(rng.standard_normal(period), n_sec)  # exactly periodic, no shorter period
        got = classify_period(sections, n_lobes=n_lobes, max_order=max_order)
        assert (got.period == period) == found, (period, got)
        assert found or got.code == PeriodClass.NONE


def test_the_sweep_figure_names_the_window_s_bound(monkeypatch, tmp_path):
    from types import SimpleNamespace

    from pipelines.scene import load_scene
    from pipelines.stages import ti as ti_stage
    from pipelines.stages.base import Context

    scene_path = Path(__file__).resolve().parents[2] / "scenes" / "rotor67_coarse.toml"
    seen = {}
    monkeypatch.setattr(ti_stage, "read_sweep", lambda out: SimpleNamespace(omega=OMEGA, amplitude=AMPLITUDE,
                                                                               period_class=CLASSES,
                                                                               explicit_direction_steps=None))
    monkeypatch.setattr(figures, "plot_ti_sweep", lambda *a, **kw: seen.update(kw))
    (tmp_path / ti_stage.TI.file).touch()  # read_sweep's stand-in reads nothing
    for n_keep, expected in ((20, 10.0), (30, 15.0)):
        scene = load_scene(scene_path, ["ti.max_order=15", f"ti.n_keep={n_keep}"])
        ti_stage.draw_sweep(Context(scene, tmp_path, None))
        assert seen["max_order"] == expected
