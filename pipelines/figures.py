"""Result figures in the style of Vadcard et al. (2022), drawn with matplotlib's Agg backend.

Inputs are SI (m, s, rad/s); lengths are drawn in mm unless told otherwise. Every
function writes one PNG of exactly ``figsize * dpi`` pixels and returns its path.
"""
from __future__ import annotations

import textwrap
from fractions import Fraction
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # no display anywhere in the pipeline
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402

from hbm.options import TimeIntegrationOptions  # noqa: E402
from hbm.ti.periodicity import PeriodClass  # noqa: E402
from pipelines import artifacts as art  # noqa: E402

#: Marker, colour and label (a template of n, the number of lobes n_l, and max_order, the
#: largest subharmonic order nu = Ω / ω the sweep's classifier tried:
#: TimeIntegrationOptions.classified_order) of each periodicity class of a time-integration
#: point; hbm.ti.periodicity.PeriodClass codes.
PERIODICITY = {
    PeriodClass.CASING: ("\u03c9 = {n}\u03a9", "o", "#111111"),
    PeriodClass.REVOLUTION: ("\u03c9 = \u03a9", "^", "#1f77b4"),
    PeriodClass.SUPERHARMONIC: ("\u03a9 < \u03c9 < {n}\u03a9", "v", "#d62728"),
    PeriodClass.SUBHARMONIC: ("subharmonic (\u03c9 < \u03a9)", "s", "#2ca02c"),
    PeriodClass.NONE: ("no periodicity or \u03c9 < \u03a9/{max_order:g}", "D", "#9a9a9a"),
}
_LENGTH = {"m": 1.0, "mm": 1e3, "um": 1e6}
#: smallest area (pt^2) of the ring around a flagged TI point: 10 pt across, twice a fold's
#: open circle (ms 5), so that the two never read alike
FLAG_RING_MIN = 100.0
FIGSIZE = (7.0, 4.5)  # inches
#: the amplitude-against-speed figures (Figs. 5, 6 and 8), whose legend stands right of the
#: axes (_legend_outside): the axes keep about FIGSIZE's width
WIDE_FIGSIZE = (9.5, 4.5)
DPI = 150


def _save(fig, out_png) -> Path:
    """Write `fig` to out_png through a temporary file: a drawing that fails (a full disk,
    Ctrl-C) leaves the previous picture as it was, and a folder copied with hard links keeps
    its own."""
    out_png = Path(out_png)
    try:
        with art.atomic_output(out_png) as tmp:
            # the temporary name has no suffix, so the format is named; no bbox_inches="tight":
            # the pixel size stays fixed
            fig.savefig(tmp, dpi=DPI, format=out_png.suffix.lstrip(".") or "png")
    finally:
        plt.close(fig)
    return out_png


#: legend entry of the ringed TI points (the caller may name its criterion instead)
FLAGGED_LABEL = "TI: friction direction not settled"


def _scatter_classes(ax, omega, amplitude, classes, *, faded=False, size=18, n_lobes=2,
                     max_order=TimeIntegrationOptions.max_order, flagged=None, flagged_label=FLAGGED_LABEL):
    """Markers per periodicity class; `faded` greys out all but the casing-periodic ones
    (ω = n_l Ω, Fig. 6). Only the classes present get a legend entry, except ω = n_l Ω and
    ω = Ω, always listed (the paper's legend). max_order: the largest order the sweep's
    classifier tried (`[ti] max_order`, or less: TimeIntegrationOptions.classified_order),
    named in the label of "no periodicity". flagged: (p,) bool or None, points ringed in
    black (points whose march the reader should not take at face value), with one legend
    entry `flagged_label` when any is."""
    omega, amplitude, classes = (np.asarray(a).ravel() for a in (omega, amplitude, classes))
    ring = np.zeros(omega.shape, bool) if flagged is None else np.asarray(flagged, bool).ravel()
    if ring.shape != omega.shape:
        raise ValueError(f"flagged: {ring.shape[0]} flags for {omega.shape[0]} speeds")
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
                              label=f"TI: {label.format(n=n_lobes, max_order=max_order)}"))
    if ring.any():
        # dashed and wider than a fold's open circle (Fig. 8 marks folds with ms 5): a solid
        # ring of 3.2 size read as one there
        rings = ax.scatter(omega[ring], amplitude[ring], s=max(3.2 * size, FLAG_RING_MIN), marker="o",
                           facecolors="none", edgecolors="black", linewidths=0.9, linestyles=(0, (2.0, 1.2)),
                           zorder=4)
        rings.set_label(flagged_label)
        handles.append(rings)  # the collection itself: a Line2D marker cannot have a dashed edge
    return handles


def _amplitude_axes(ax, omega_range, unit: str, title: str | None) -> None:
    """Axes of the amplitude-vs-speed figures (Fig. 5 and 6 of the paper)."""
    lo, hi = omega_range
    if hi <= lo:  # a sweep of one speed: a window of 2 % around it
        pad = max(1.0, 0.02 * abs(lo))
        lo, hi = lo - pad, hi + pad
    ax.set_xlim(lo, hi)
    ax.set_ylim(bottom=0.0)
    ax.set_xlabel("angular speed \u03a9 (rad/s)")
    ax.set_ylabel(f"LE radial amplitude, half peak-to-peak ({unit})")
    ax.grid(True, lw=0.4, alpha=0.5)
    if title:
        ax.set_title(title)


def _legend_outside(ax, handles, fontsize: float = 7):
    """The legend right of the axes. Inside, wherever it went, it hid what it names: Fig. 8's
    primary NFRC of the coarse rotor 67 scene (1.5-1.9 mm at 400-1450 rad/s) under its upper
    left corner, the default scene's ringed sweep points near 1250 rad/s under Fig. 6's "best"
    place. More entries than a column of the page's height holds (a row takes 1.56 to 1.6
    times the font size, measured at 6 and 7 pt) go into more columns, so that none is cut off
    below the page."""
    rows = max(1, int((72.0 * WIDE_FIGSIZE[1] - 12.0) / (1.6 * fontsize)))
    lines = sum(1 + str(h.get_label()).count("\n") for h in handles)
    return ax.legend(handles=handles, fontsize=fontsize, loc="upper left", bbox_to_anchor=(1.01, 1.0),
                     borderaxespad=0.0, framealpha=0.9, ncol=max(1, -(-lines // rows)))


def plot_nfrc(curves: dict, out_png, ti_points=None, *, omega_range=(400.0, 2000.0),
              unit: str = "mm", title: str | None = None, fade_other_classes: bool = True,
              n_lobes: int = 2, max_order: float = TimeIntegrationOptions.max_order,
              flagged_label: str = FLAGGED_LABEL) -> Path:
    """Nonlinear frequency response curves (paper Fig. 6): LE radial amplitude vs Ω.

    curves: {label: (omega (m,) rad/s, amplitude (m,) m, converged (m,) bool or None)}, one
    line per method, drawn in the order of the points (a continuation path); points not
    converged break the line and are marked with a small grey cross where they fall inside
    the axes the others set (a failed point's amplitude is a diverged iterate's); a curve
    without a converged point is labelled so. Labels containing
    "isola" are dashed. ti_points: optional (omega (p,) rad/s, amplitude (p,) m, classes (p,)
    int, PeriodClass codes[, flagged (p,) bool]) drawn as markers shaped by class; as in the
    paper, all but the casing-periodic ones (ω = n_l Ω) are grey unless fade_other_classes is
    False; flagged points are ringed, named flagged_label in the legend.
    unit: "m", "mm" or "um" for the amplitude axis. n_lobes: n_l, for the class labels.
    max_order: the largest subharmonic order the sweep's classifier tried
    (TimeIntegrationOptions.classified_order), for the label of "no periodicity"; the default
    is TimeIntegrationOptions'.
    """
    k = _LENGTH[unit]
    fig, ax = plt.subplots(figsize=WIDE_FIGSIZE, constrained_layout=True)
    handles, any_failed = [], False
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for i, (label, curve) in enumerate(curves.items()):
        omega, amplitude = np.asarray(curve[0], float), k * np.asarray(curve[1], float)
        ok = np.ones(omega.shape, bool) if len(curve) < 3 or curve[2] is None else np.asarray(curve[2], bool)
        style = "--" if "isola" in label.lower() else "-"
        colour = colours[i % len(colours)]
        if not ok.any():  # e.g. a start point that converged at neither end of the range
            label = f"{label} (no converged point)"
        (line,) = ax.plot(omega, np.where(ok, amplitude, np.nan), style, color=colour, lw=1.4, label=label)
        handles.append(line)
        if not ok.all():
            any_failed = True
            # a failed point's amplitude is that of the iterate Newton gave up on (a start that
            # did not converge gave 120 mm): marked where it falls inside the range of the rest,
            # never stretching the axes over it (add_artist, unlike plot, leaves the data
            # limits that autoscaling reads alone)
            ax.add_artist(Line2D(omega[~ok], amplitude[~ok], ls="none", marker="x", color="0.55", ms=3, zorder=2))
    if any_failed:
        handles.append(Line2D([], [], ls="none", marker="x", color="0.55", label="not converged"))
    if ti_points is not None:
        o, a, c, *flags = ti_points
        handles += _scatter_classes(ax, o, k * np.asarray(a, float), c, faded=fade_other_classes,
                                    n_lobes=n_lobes, max_order=max_order, flagged=flags[0] if flags else None,
                                    flagged_label=flagged_label)
    _amplitude_axes(ax, omega_range, unit, title)
    _legend_outside(ax, handles)
    return _save(fig, out_png)


def plot_ti_sweep(omega, amplitude, classes, out_png, *, omega_range=(400.0, 2000.0),
                  unit: str = "mm", title: str | None = None, n_lobes: int = 2,
                  max_order: float = TimeIntegrationOptions.max_order, flagged=None,
                  flagged_label: str = FLAGGED_LABEL) -> Path:
    """Time-integration sweep (paper Fig. 5): one marker per simulated Ω, shaped and
    coloured by periodicity class.

    omega: (p,) rad/s; amplitude: (p,) m (LE radial amplitude); classes: (p,) int
    PeriodClass codes (ω = n_l Ω, ω = Ω, Ω < ω < n_l Ω, subharmonic, none or ω < Ω / max_order).
    n_lobes: n_l, for the class labels. max_order: as in plot_nfrc. flagged: (p,) bool or
    None, points whose march the reader should not take at face value (the ti stage: those
    its fallback WARNING names), ringed in black with `flagged_label` in the legend.
    """
    fig, ax = plt.subplots(figsize=WIDE_FIGSIZE, constrained_layout=True)
    handles = _scatter_classes(ax, omega, _LENGTH[unit] * np.asarray(amplitude, float), classes, size=22,
                               n_lobes=n_lobes, max_order=max_order, flagged=flagged, flagged_label=flagged_label)
    _amplitude_axes(ax, omega_range, unit, title)
    # every point is a TI point here: the legend drops the "TI: " prefix
    for h in handles:
        h.set_label(h.get_label().removeprefix("TI: "))
    _legend_outside(ax, handles)
    return _save(fig, out_png)


# -- the solution set and the validation points (Figs. 8 to 12) -------------------------------
#: Pixel size of the multi-panel figures (Figs. 9 and 10), inches at DPI.
GRID_FIGSIZE = (11.0, 9.0)
#: Line colour of each branch kind, per treatment (first, second); stability sets the style.
KIND_COLOURS = {
    "primary": ("#1f77b4", "#d62728"),
    "isola": ("#2ca02c", "#9467bd"),
    "bifurcated": ("#ff7f0e", "#8c564b"),
    "period-doubled": ("#17becf", "#e377c2"),
    "detached": ("#7f7f7f", "#bcbd22"),
    "friction lock": ("#000000", "#006400"),  # a node held on the casing past mu_set: the model's, not the blade's
}
#: Line style by stability: stable, unstable, unknown.
STABILITY_STYLES = {"stable": "-", "unstable": "--", "unknown": ":"}
#: Marker of each bifurcation kind (hbm.stability.bifurcation.KINDS).
BIFURCATION_MARKERS = {"fold": "o", "branch point": "s", "period doubling": "D", "Neimark-Sacker": "*",
                       "unclassified": "x", "validation point": "P"}
#: colour of a bifurcation whose kind is a guess (Bifurcation.kind_from "guess")
GUESSED = "0.6"


def _stability_runs(stable, converged, n_unstable=None):
    """Runs [(start, stop, state)] of equal state ("stable", "unstable", "unknown") over the
    converged points; a run ends one point into the next so that the curve stays connected.
    stable None: all unknown; n_unstable (m,) int, given: unknown where it is -1 (no verdict,
    stored with stable False, which is not "unstable")."""
    n = len(converged)
    state = np.array(["unknown"] * n, dtype=object) if stable is None else \
        np.where(np.asarray(stable, bool), "stable", "unstable").astype(object)
    if stable is not None and n_unstable is not None:
        state[np.asarray(n_unstable) < 0] = "unknown"
    runs, i = [], 0
    while i < n:
        if not converged[i]:
            i += 1
            continue
        j = i
        while j + 1 < n and converged[j + 1] and state[j + 1] == state[i]:
            j += 1
        runs.append((i, min(j + 2, n) if j + 1 < n and converged[j + 1] else j + 1, state[i]))
        i = j + 1
    return runs


#: opacity of a branch none of whose checked points holds with twice the harmonics (Fig. 8)
TRUNCATED_ALPHA = 0.3


def plot_solution_set(curves: dict, out_png, ti_points=None, *, omega_range=(400.0, 2000.0), unit: str = "mm",
                      title: str | None = None, n_lobes: int = 2,
                      max_order: float = TimeIntegrationOptions.max_order, flagged_label: str = FLAGGED_LABEL) -> Path:
    """The solution set (paper Fig. 8): every branch's LE amplitude against Omega, stable parts
    solid, unstable dashed, stability unknown dotted; the bifurcations given marked by kind; the TI
    sweep's points by periodicity class. Each branch is drawn in its points' order; a point not
    converged, or with a NaN Omega or amplitude, is not drawn and breaks the line. The segment
    between two points of different stability (where it changes) takes the style of the first
    of the two in the branch's order (_stability_runs: each run reaches one point into the
    next, so that the curve stays connected): the change lies somewhere on that segment, and
    the bifurcation located there, given in marks, is drawn on it.

    curves: {treatment label: (lines, marks)}; lines: [(kind, omega (m,) rad/s, amplitude
    (m,) m, converged (m,) bool, stable (m,) bool or None[, n_unstable (m,) int or None[,
    truncated bool]])], kind one of KIND_COLOURS, n_unstable -1 drawn as unknown; truncated:
    no point of the branch holds with twice the harmonics (isolas.h5's harmonic_check "not
    converged"): drawn faded (TRUNCATED_ALPHA), a solution of the truncation only;
    marks: [(bifurcation kind, omega rad/s, amplitude m[, guessed])], guessed (default False):
    the kind is a guess (no multiplier paired across the circle and the parities of the real
    ones do not tell, Bifurcation.kind_from), drawn
    grey. ti_points, max_order, flagged_label as in plot_nfrc.
    """
    k = _LENGTH[unit]
    fig, ax = plt.subplots(figsize=WIDE_FIGSIZE, constrained_layout=True)
    handles, seen_styles, seen_marks, seen_guess, seen_faded = [], set(), set(), False, False
    for t, (label, (lines, marks)) in enumerate(curves.items()):
        for kind, omega, amp, conv, stable, *rest in lines:
            colour = KIND_COLOURS.get(kind, KIND_COLOURS["detached"])[t % 2]
            omega, amp = np.asarray(omega, float), k * np.asarray(amp, float)
            conv = np.asarray(conv, bool)
            faded = len(rest) > 1 and bool(rest[1])
            seen_faded = seen_faded or faded
            runs = _stability_runs(stable, conv, rest[0] if rest else None)
            for a, b, state in runs:
                ax.plot(omega[a:b], amp[a:b], STABILITY_STYLES[state], color=colour, lw=1.3,
                        alpha=TRUNCATED_ALPHA if faded else 1.0)
                seen_styles.add(state)
            if runs:  # a branch without a converged point (an NFRC that never started) draws nothing
                handles.append(Line2D([], [], color=colour, lw=1.3, label=f"{label} {kind}"))
        for kind, w, a, *guessed in marks:
            if np.isfinite(a):
                grey = bool(guessed and guessed[0])
                ax.plot(w, k * a, BIFURCATION_MARKERS.get(kind, "x"), color=GUESSED if grey else "k", ms=5,
                        mfc="none", zorder=4)
                seen_marks.add(kind)
                seen_guess = seen_guess or grey
    uniq = {h.get_label(): h for h in handles}
    handles = list(uniq.values())
    handles += [Line2D([], [], color="0.3", ls=STABILITY_STYLES[s], label=s) for s in STABILITY_STYLES if s in seen_styles]
    handles += [Line2D([], [], ls="none", marker=BIFURCATION_MARKERS.get(m, "x"), color="k", mfc="none", label=m)
                for m in BIFURCATION_MARKERS if m in seen_marks]
    if seen_guess:
        # a grey patch, not a marker: a guessed mark keeps its kind's marker, so a grey circle
        # here would read as "fold"
        handles.append(Patch(facecolor=GUESSED, edgecolor=GUESSED, label="kind guessed (its marker in grey)"))
    if seen_faded:
        handles.append(Line2D([], [], color="0.3", lw=1.3, alpha=TRUNCATED_ALPHA,
                              label="faded: not converged with 2 N_h"))
    if ti_points is not None:
        o, a, c, *flags = ti_points
        handles += _scatter_classes(ax, o, k * np.asarray(a, float), c, faded=True, n_lobes=n_lobes, size=10,
                                    max_order=max_order, flagged=flags[0] if flags else None,
                                    flagged_label=flagged_label)
    if not curves or not any(lines for lines, _ in curves.values()):
        ax.text(0.5, 0.5, "no branch computed yet", transform=ax.transAxes, ha="center", color="0.4")
    _amplitude_axes(ax, omega_range, unit, title)
    _legend_outside(ax, handles, fontsize=6)
    return _save(fig, out_png)


def _note(ax, text: str) -> None:
    import textwrap

    ax.text(0.5, 0.5, "\n".join(textwrap.wrap(text, 60)), transform=ax.transAxes, ha="center", va="center",
            fontsize=7, color="0.35")
    ax.set_xticks([])
    ax.set_yticks([])


#: Colours of the signals in Figs. 9 and 10.
SIGNAL_COLOURS = {"dlft": "#1f77b4", "rl": "#d62728", "ti": "#111111"}


def plot_validation_signals(points: dict, out_png, *, title: str | None = None, verdict=None) -> Path:
    """Time signals at the validation points (paper Fig. 9): one row per point (primary, isola,
    period-doubled), radial displacement and normal contact force at the LE (solid) and TE
    (dashed): DLFT-HBM, RL-HBM and time integration over the orbit's last period.

    points: {kind: a pipelines.stages.validation.ValidationPoint (found, reason, omega,
    subharmonic, ti, dlft, rl, refined_from)}. A point not found gets its reason written in its
    row; a point marched again with a finer step gets that step and the first march's verdict.
    verdict: the words of a march's verdict in each row's title, verdict(ti) -> str; default
    ti.verdict(), which cannot tell the friction lock from other permanent contact (that
    needs the ROM's mu_set: the validation stage passes its ti_verdict).
    """
    verdict = verdict or (lambda ti: ti.verdict())
    fig, axes = plt.subplots(len(points), 2, figsize=GRID_FIGSIZE, constrained_layout=True, squeeze=False)
    for row, (kind, p) in zip(axes, points.items()):
        name = kind.replace("_", " ")
        if not p.found:
            for ax in row:
                _note(ax, f"{name}: none ({p.reason})")
            continue
        t = 1e3 * p.ti.tau * p.subharmonic / p.omega  # ms
        for ax, what, scale, unit in ((row[0], "displacement", 1e3, "mm"), (row[1], "force", 1.0, "N")):
            for col, ls, end in ((0, "-", "LE"), (2, "--", "TE")):
                ax.plot(t, scale * getattr(p.ti, what)[:, col], ls, color=SIGNAL_COLOURS["ti"], lw=1.6, alpha=0.6,
                        label=f"TI {end}")
                for m in ("dlft", "rl"):
                    c = getattr(p, m)
                    if c is not None and c.converged:
                        ax.plot(t, scale * getattr(c, what)[:, col], ls, color=SIGNAL_COLOURS[m], lw=1.0,
                                label=f"{m.upper()}-HBM {end}")
            ax.set_xlim(t.min(), t.max())
            ax.grid(True, lw=0.4, alpha=0.5)
            ax.set_ylabel(f"{'radial displacement' if what == 'displacement' else 'normal force'} ({unit})", fontsize=8)
            stab = "stable" if p.stable else "unstable"
            # a march repeated with a finer step says so, and what the first one did, as the log does
            first = getattr(p, "refined_from", "")
            refined = f"; dt = {p.ti.dt:.3g} s, the first march {first}" if first else ""
            # the verdict can be long (the friction lock names its nodes): wrapped, not cut at the edge
            # an orbit of nu revolutions (a period-doubled branch's, nu = 2) spans nu of them here
            nu = f", \u03bd = {p.subharmonic}" if p.subharmonic > 1 else ""
            ax.set_title(textwrap.fill(f"{name}, \u03a9 = {p.omega:.1f} rad/s{nu} ({stab}, TI {verdict(p.ti)}"
                                       f"{refined})", 80), fontsize=8)
        row[0].legend(fontsize=6, loc="best", ncol=3)
    for ax in axes[-1]:
        ax.set_xlabel("time (ms)")
    if title:
        fig.suptitle(title, fontsize=9)
    return _save(fig, out_png)


def plot_contact_event(point, out_png, *, title: str | None = None) -> Path:
    """Close view of a contact event (paper Fig. 10): radial displacement of the LE and of the
    second boundary node against the casing profile d_j(t), DLFT-HBM, RL-HBM and time
    integration, around the TI orbit's closest approach to the casing at the LE.

    point: a ValidationPoint (found, ti with tau, distance, displacement; dlft, rl).
    """
    fig, axes = plt.subplots(2, 1, figsize=GRID_FIGSIZE, constrained_layout=True)
    if not point.found:
        for ax in axes:
            _note(ax, f"no point ({point.reason})")
        return _save(fig, out_png)
    ti = point.ti
    n = len(ti.tau)
    t = 1e3 * ti.tau * point.subharmonic / point.omega
    d = ti.distance[:, 0]
    i0 = int(np.argmin(d - ti.displacement[:, 0]))
    lobe = d < 0.5 * (d.max() + d.min())  # the lobe's stretch around the closest approach
    a = b = i0
    while lobe[(a - 1) % n] and b - a < n - 1:
        a -= 1
    while lobe[(b + 1) % n] and b - a < n - 1:
        b += 1
    half = max(8, int(0.75 * (b - a + 1)))
    sel = np.arange(i0 - half, i0 + half + 1) % n
    tt = t[i0] + (np.arange(-half, half + 1)) * (t[1] - t[0])
    for ax, col, name in ((axes[0], 0, "LE"), (axes[1], 1, f"boundary node {int(ti.nodes[1]) + 1}")):
        ax.plot(tt, 1e3 * ti.distance[sel, col], color="0.5", lw=3, alpha=0.6, label="casing")
        ax.plot(tt, 1e3 * ti.displacement[sel, col], color=SIGNAL_COLOURS["ti"], lw=1.6, label="TI")
        for m in ("dlft", "rl"):
            c = getattr(point, m)
            if c is not None and c.converged:
                ax.plot(tt, 1e3 * c.displacement[sel, col], color=SIGNAL_COLOURS[m], lw=1.0, label=f"{m.upper()}-HBM")
        ax.set_ylabel(f"{name} radial displacement (mm)", fontsize=8)
        ax.grid(True, lw=0.4, alpha=0.5)
        ax.legend(fontsize=7, loc="best")
    axes[1].set_xlabel("time (ms)")
    if title:
        fig.suptitle(title, fontsize=9)
    return _save(fig, out_png)


#: Panels of the content figures (Figs. 11-12): more branches than this are in isolas.h5 only.
MAX_CONTENT_PANELS = 8


def _times_omega(k) -> str:
    """k Omega written out: "4Ω", "Ω", "3Ω/2", "Ω/2"."""
    k = Fraction(k)
    num = "" if k.numerator == 1 else f"{k.numerator}"
    return f"{num}\u03a9" + ("" if k.denominator == 1 else f"/{k.denominator}")


def plot_content(curves: dict, out_png, *, kind: str = "modal", harmonics=(2, 4, 6, 8, 10), n_modes: int = 4,
                 mode_frequencies=None, max_panels: int = MAX_CONTENT_PANELS) -> Path:
    """Dynamical content along branches (paper Figs. 11 and 12) against Omega, one panel per
    branch, each drawn in its points' order (an isola is a loop in these planes too).

    curves: {label: (omega (m,) rad/s, contributions (m, n), nu[, converged (m,) bool])}, nu the
    branch's subharmonic order (its harmonic i oscillates at i Omega / nu; (omega, contributions)
    means nu = 1); converged, given: the points not converged are not drawn (a gap in the line).
    kind "modal": contributions are eq. (33)'s relative modal contributions
    (column j: mode j + 1, the modes in ascending frequency); the first `n_modes` modes are
    drawn and the rest summed, as in Fig. 11, with the 0.5 line; given mode_frequencies, each
    mode's label carries its frequency. kind "harmonic": column i is |c_i| of the LE radial
    displacement, m (eq. 34), harmonic i of the branch's basis Omega / nu. Every harmonic is
    drawn, labelled and coloured by its frequency k Omega, k = i / nu (Fig. 12's k: the paper's
    branches have nu = 1), so that one k has one colour in every panel, whatever the panel's nu:
    `harmonics` are such k (the paper's 2, 4, ..., 10: columns 2 nu, 4 nu, ..., 10 nu), drawn
    where they carry content (the five largest columns where none does), with the branch's
    largest harmonic besides (k = 3/2 on a nu = 2 branch: "k = 3/2"). Given mode_frequencies
    ((n,) rad/s), every crossing k Omega = omega_j of a drawn k with one of the first n_modes
    modes inside the panel's span is marked (Fig. 12's dashed lines). The max_panels branches
    with the most points are drawn when there are more; a branch without any finite
    contribution is left out.
    """
    def masked(v):  # a point not converged (its 4th item, optional) is left out: the line breaks there
        c = np.asarray(v[1], float)
        if len(v) > 3 and v[3] is not None:
            c = np.where(np.asarray(v[3], bool)[:, None], c, np.nan)
        return (v[0], c, v[2] if len(v) > 2 else 1)

    # a branch with no finite contribution (none of its points converged) has nothing to draw
    items = [(k, v) for k, v in ((k, masked(v)) for k, v in curves.items()) if np.isfinite(v[1]).any()]
    dropped = max(0, len(items) - max_panels)
    if dropped:
        keep = sorted(sorted(range(len(items)), key=lambda i: -len(items[i][1][0]))[:max_panels])
        items = [items[i] for i in keep]
    ncols = 2 if len(items) > 1 else 1
    nrows = max(1, -(-len(items) // ncols))
    size = (FIGSIZE[0] * (1.0 if ncols == 1 else 1.5), max(FIGSIZE[1], 2.1 * nrows + 1.2))
    fig, axes = plt.subplots(nrows, ncols, figsize=size, constrained_layout=True, squeeze=False)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    handles = {}
    drawn, k_colour = {}, {}
    if kind != "modal":
        for label, entry in items:
            c = np.asarray(entry[1], float)
            nu = int(entry[2])
            # harmonics are multiples k of Omega: column nu k of a branch of basis Omega / nu (k = 2 is
            # column 4 on a nu = 2 branch, where column 2 is Omega itself)
            cols_k = [Fraction(h).limit_denominator(1000) * nu for h in harmonics]
            ks = [int(i) for i in cols_k if i.denominator == 1 and 0 <= i < c.shape[1]
                  and np.nanmax(c[:, int(i)]) > 1e-3 * np.nanmax(c)]
            ks = ks or sorted(int(k) for k in np.argsort(-np.nanmax(c, axis=0))[:5])
            top = 1 + int(np.nanargmax(np.nanmax(c[:, 1:], axis=0))) if c.shape[1] > 1 else 0
            # the dominant harmonic, e.g. the 3rd of a 3 Omega = omega_1 isola; kept as (column, k Omega)
            drawn[label] = [(i, Fraction(i, nu)) for i in sorted(set(ks) | {top})]
        # one colour per frequency k Omega over all panels, none shared (the same k the same colour on
        # branches of Omega and of Omega / 2): an integer k < 10 keeps the colour cycle's k-th, a higher
        # or fractional k (k = 12 once shared k = 2's) takes one of colours unused so far
        every = sorted({k for ks in drawn.values() for _, k in ks})
        k_colour = {k: colours[int(k)] for k in every if k.denominator == 1 and k < len(colours)}
        high = [k for k in every if k not in k_colour]
        extra = [matplotlib.colors.to_hex(plt.cm.tab20(i)) for i in range(1, 20, 2)]
        if len(high) > len(extra):
            extra = [matplotlib.colors.to_hex(plt.cm.turbo(v)) for v in np.linspace(0.05, 0.95, len(high))]
        k_colour.update(zip(high, extra))
    for ax, (label, entry) in zip(axes.ravel(), items):
        omega, c = np.asarray(entry[0], float), np.asarray(entry[1], float)
        nu = int(entry[2]) if len(entry) > 2 else 1
        if kind == "modal":
            freq = None if mode_frequencies is None else np.asarray(mode_frequencies, float)
            cols = [(j, f"mode {j + 1}" + (f" ({freq[j]:.0f} rad/s)" if freq is not None and j < len(freq) else ""),
                     colours[j % len(colours)]) for j in range(min(n_modes, c.shape[1]))]
            lines = [c[:, j] for j, _, _ in cols]
            if c.shape[1] > n_modes:
                cols.append((n_modes, f"modes {n_modes + 1} to {c.shape[1]}", "0.45"))
                lines.append(c[:, n_modes:].sum(axis=1))
            ax.axhline(0.5, color="0.5", lw=0.8, ls=":")
            ax.set_ylim(0.0, 1.0)
        else:
            cols = [(k, f"k = {k}", k_colour[k]) for _, k in drawn[label]]  # k: the frequency k Omega
            lines = [1e3 * c[:, i] for i, _ in drawn[label]]
        for (key, name, colour), y in zip(cols, lines):
            ax.plot(omega, y, color=colour, lw=1.0)
            handles.setdefault(key, Line2D([], [], color=colour, lw=1.2, label=name))
        lo, hi = np.nanmin(omega), np.nanmax(omega)
        pad = 0.03 * (hi - lo) + 1e-9
        ax.set_xlim(lo - pad, hi + pad)
        if kind == "harmonic" and mode_frequencies is not None:
            for k, _, colour in cols:
                for j, wj in enumerate(np.asarray(mode_frequencies, float)[:n_modes]):
                    at = float(wj / k) if k else np.inf  # k Omega = omega_j
                    if lo - pad <= at <= hi + pad:
                        ax.axvline(at, color=colour, lw=0.8, ls="--")
                        ax.annotate(f"{_times_omega(k)} = \u03c9{j + 1}", (at, 1.0),
                                    xycoords=("data", "axes fraction"), fontsize=6, rotation=90,
                                    ha="right", va="top", color=colour)
        ax.set_title(f"{label}, \u03a9 {lo:.0f}-{hi:.0f} rad/s" + (f" (basis \u03a9/{nu})" if nu > 1 else ""),
                     fontsize=8)
        ax.grid(True, lw=0.4, alpha=0.5)
        ax.tick_params(labelsize=7)
    for ax in axes.ravel()[len(items):]:
        ax.set_axis_off()
    for ax in axes[-1]:
        ax.set_xlabel("angular speed \u03a9 (rad/s)", fontsize=8)
    for ax in axes[:, 0]:
        ax.set_ylabel("relative modal contribution (-)" if kind == "modal" else "|c_k|, LE radial (mm)", fontsize=8)
    if not items:
        _note(axes[0, 0], f"no {kind} contributions in the solution set")
    else:
        entries = [h for _, h in sorted(handles.items())]  # by mode or harmonic, whichever panel drew it first
        # the harmonics' legend says what k is: the frequency k Omega, on any branch's basis
        fig.legend(handles=entries, loc="outside lower center", ncol=min(len(entries), 6), fontsize=7,
                   title=None if kind == "modal" else "harmonic of frequency k\u03a9", title_fontsize=7)
    if dropped:
        fig.suptitle(f"{len(items)} branches with the most points drawn of {len(items) + dropped}; all are in "
                     "isolas.h5", fontsize=8)
    return _save(fig, out_png)
