"""Result figures in the style of Vadcard et al. (2022), drawn with matplotlib's Agg backend.

Inputs are SI (m, s, rad/s); lengths are drawn in mm unless told otherwise. Every
function writes one PNG of exactly ``figsize * dpi`` pixels and returns its path.
"""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # no display anywhere in the pipeline
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402

from hbm.ti.periodicity import PeriodClass  # noqa: E402

#: Marker, colour and label (a template of n_l, the number of lobes) of each periodicity
#: class of a time-integration point; hbm.ti.periodicity.PeriodClass codes.
PERIODICITY = {
    PeriodClass.CASING: ("\u03c9 = {n}\u03a9", "o", "#111111"),
    PeriodClass.REVOLUTION: ("\u03c9 = \u03a9", "^", "#1f77b4"),
    PeriodClass.SUPERHARMONIC: ("\u03a9 < \u03c9 < {n}\u03a9", "v", "#d62728"),
    PeriodClass.SUBHARMONIC: ("subharmonic (\u03c9 < \u03a9)", "s", "#2ca02c"),
    PeriodClass.NONE: ("no periodicity or \u03c9 < \u03a9/10", "D", "#9a9a9a"),
}
_LENGTH = {"m": 1.0, "mm": 1e3, "um": 1e6}
FIGSIZE = (7.0, 4.5)  # inches
DPI = 150


def _save(fig, out_png) -> Path:
    out_png = Path(out_png)
    out_png.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out_png, dpi=DPI)  # no bbox_inches="tight": the pixel size stays fixed
    plt.close(fig)
    return out_png


def _scatter_classes(ax, omega, amplitude, classes, *, faded=False, size=18, n_lobes=2):
    """Markers per periodicity class; `faded` greys out all but the casing-periodic ones
    (ω = n_l Ω, Fig. 6). Only the classes present get a legend entry, except ω = n_l Ω and
    ω = Ω, always listed (the paper's legend)."""
    omega, amplitude, classes = (np.asarray(a).ravel() for a in (omega, amplitude, classes))
    unknown = set(np.unique(classes).tolist()) - {int(c) for c in PERIODICITY}
    if unknown:
        raise ValueError(f"unknown periodicity class codes {sorted(unknown)}; known: "
                         f"{', '.join(f'{int(c)} ({c.name})' for c in PeriodClass)}")
    handles = []
    for code, (label, marker, colour) in PERIODICITY.items():
        pick = classes == code
        if not pick.any() and code not in (PeriodClass.CASING, PeriodClass.REVOLUTION):
            continue
        if faded and code != PeriodClass.CASING:
            colour = "#b8b8b8"
        ax.scatter(omega[pick], amplitude[pick], s=size, marker=marker, color=colour,
                   edgecolors="none", zorder=3)
        handles.append(Line2D([], [], ls="none", marker=marker, color=colour,
                              label=f"TI: {label.format(n=n_lobes)}"))
    return handles


def _amplitude_axes(ax, omega_range, unit: str, title: str | None) -> None:
    """Axes of the amplitude-vs-speed figures (Fig. 5 and 6 of the paper)."""
    ax.set_xlim(*omega_range)
    ax.set_ylim(bottom=0.0)
    ax.set_xlabel("angular speed \u03a9 (rad/s)")
    ax.set_ylabel(f"LE radial amplitude, half peak-to-peak ({unit})")
    ax.grid(True, lw=0.4, alpha=0.5)
    if title:
        ax.set_title(title)
    ax.set_ylim(0.0, 1.12 * ax.get_ylim()[1])  # head room for the legend


def plot_nfrc(curves: dict, out_png, ti_points=None, *, omega_range=(400.0, 2000.0),
              unit: str = "mm", title: str | None = None, fade_other_classes: bool = True,
              n_lobes: int = 2) -> Path:
    """Nonlinear frequency response curves (paper Fig. 6): LE radial amplitude vs Ω.

    curves: {label: (omega (m,) rad/s, amplitude (m,) m, converged (m,) bool or None)}, one
    line per method, drawn in the order of the points (a continuation path); points not
    converged break the line and are marked with a small grey cross. Labels containing
    "isola" are dashed. ti_points: optional (omega (p,) rad/s, amplitude (p,) m, classes (p,)
    int, PeriodClass codes) drawn as markers shaped by class; as in the paper, all but the
    casing-periodic ones (ω = n_l Ω) are grey unless fade_other_classes is False.
    unit: "m", "mm" or "um" for the amplitude axis. n_lobes: n_l, for the class labels.
    """
    k = _LENGTH[unit]
    fig, ax = plt.subplots(figsize=FIGSIZE, constrained_layout=True)
    handles, any_failed = [], False
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for i, (label, curve) in enumerate(curves.items()):
        omega, amplitude = np.asarray(curve[0], float), k * np.asarray(curve[1], float)
        ok = np.ones(omega.shape, bool) if len(curve) < 3 or curve[2] is None else np.asarray(curve[2], bool)
        style = "--" if "isola" in label.lower() else "-"
        colour = colours[i % len(colours)]
        (line,) = ax.plot(omega, np.where(ok, amplitude, np.nan), style, color=colour, lw=1.4, label=label)
        handles.append(line)
        if not ok.all():
            any_failed = True
            ax.plot(omega[~ok], amplitude[~ok], "x", color="0.55", ms=3, zorder=2)
    if any_failed:
        handles.append(Line2D([], [], ls="none", marker="x", color="0.55", label="not converged"))
    if ti_points is not None:
        o, a, c = ti_points
        handles += _scatter_classes(ax, o, k * np.asarray(a, float), c, faded=fade_other_classes,
                                    n_lobes=n_lobes)
    _amplitude_axes(ax, omega_range, unit, title)
    ax.legend(handles=handles, fontsize=8, loc="best", framealpha=0.9)
    return _save(fig, out_png)


def plot_ti_sweep(omega, amplitude, classes, out_png, *, omega_range=(400.0, 2000.0),
                  unit: str = "mm", title: str | None = None, n_lobes: int = 2) -> Path:
    """Time-integration sweep (paper Fig. 5): one marker per simulated Ω, shaped and
    coloured by periodicity class.

    omega: (p,) rad/s; amplitude: (p,) m (LE radial amplitude); classes: (p,) int
    PeriodClass codes (ω = n_l Ω, ω = Ω, Ω < ω < n_l Ω, subharmonic, none or ω < Ω/10).
    n_lobes: n_l, for the class labels.
    """
    fig, ax = plt.subplots(figsize=FIGSIZE, constrained_layout=True)
    handles = _scatter_classes(ax, omega, _LENGTH[unit] * np.asarray(amplitude, float), classes, size=22,
                               n_lobes=n_lobes)
    _amplitude_axes(ax, omega_range, unit, title)
    ax.legend(handles=[Line2D([], [], ls="none", marker=h.get_marker(), color=h.get_color(),
                              label=h.get_label()[4:]) for h in handles],
              fontsize=8, loc="best", framealpha=0.9)
    return _save(fig, out_png)


def plot_time_signals(t, signals: dict, out_png, ylabel: str, *, casing=None,
                      title: str | None = None) -> Path:
    """Time signals for HBM vs TI validation (paper Fig. 9).

    t: (m,) s, drawn in ms. signals: {label: (m,) array, or (t_i (m_i,) s, y (m_i,))
    for a signal on its own time grid}, in the unit that `ylabel` states (e.g.
    "radial displacement (mm)": scale before calling). Labels containing "TE" are
    dashed. casing: optional (m,) array or scalar, the casing position, drawn grey.
    """
    t = np.asarray(t, float)
    fig, ax = plt.subplots(figsize=FIGSIZE, constrained_layout=True)
    for label, y in signals.items():
        ti, yi = (np.asarray(y[0], float), np.asarray(y[1], float)) if isinstance(y, tuple) else (t, np.asarray(y, float))
        ax.plot(1e3 * ti, yi, "--" if "TE" in label else "-", lw=1.2, label=label)
    if casing is not None:
        ax.plot(1e3 * t, np.broadcast_to(np.asarray(casing, float), t.shape), color="0.5", lw=2.5,
                alpha=0.6, label="casing", zorder=1)
    ax.set_xlim(1e3 * t.min(), 1e3 * t.max())
    ax.set_xlabel("time (ms)")
    ax.set_ylabel(ylabel)
    ax.grid(True, lw=0.4, alpha=0.5)
    if title:
        ax.set_title(title)
    ax.legend(fontsize=8, loc="best", framealpha=0.9)
    return _save(fig, out_png)


def plot_frequencies(omega, frequencies, out_png, *, labels=None, engine_orders=(1, 2, 4, 8),
                     omega_range=(400.0, 2000.0), title: str | None = None) -> Path:
    """Campbell diagram: blade natural frequencies vs Ω with engine-order lines ω = nΩ.

    omega: (m,) rad/s; frequencies: (m, k) rad/s, mode j along the speed range (a (k,)
    array is drawn as speed-independent horizontal lines). labels: optional k names
    ("1B", "1T", ...). engine_orders: the n of the straight lines ω = nΩ.
    """
    omega = np.asarray(omega, float)
    f = np.asarray(frequencies, float)
    f = np.broadcast_to(f, (omega.size, f.size)) if f.ndim == 1 else f
    fig, ax = plt.subplots(figsize=FIGSIZE, constrained_layout=True)
    for j in range(f.shape[1]):
        ax.plot(omega, f[:, j], lw=1.6, label=labels[j] if labels is not None else f"mode {j + 1}")
    top = 1.1 * float(np.nanmax(f))
    span = np.array(omega_range, float)
    for n in engine_orders:
        ax.plot(span, n * span, color="0.6", lw=0.8, ls=":")
        x = min(span[1], top / n)
        ax.annotate(f"{n}\u03a9", (x, n * x), fontsize=8, color="0.35", ha="right", va="bottom")
    ax.set_xlim(*omega_range)
    ax.set_ylim(0.0, top)
    ax.set_xlabel("angular speed \u03a9 (rad/s)")
    ax.set_ylabel("natural angular frequency \u03c9 (rad/s)")
    ax.grid(True, lw=0.4, alpha=0.5)
    if title:
        ax.set_title(title)
    ax.legend(fontsize=8, loc="upper left", framealpha=0.9)
    return _save(fig, out_png)
