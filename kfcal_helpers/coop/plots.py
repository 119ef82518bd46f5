"""Matplotlib figures of the cooperative-localization notebooks and lecture slides.

Every function returns the ``Figure``; axes carry units, figures a title.
Time axes are in seconds.  Fonts, line widths and marker sizes follow the current
rcParams (see :mod:`kfcal_helpers.style`); ``figsize`` (inches) is the function's
notebook default unless given.
"""

from __future__ import annotations

import matplotlib as mpl
import matplotlib.pyplot as plt
import numpy as np

from ..style import line_width
from .model import MEAS_LABELS, N_MEAS, STATE_LABELS

__all__ = ["plot_series", "plot_states", "plot_errors", "plot_measurements", "plot_consistency", "plot_paths",
           "plot_nis_comparison", "plot_runs_consistency", "legend_below"]



def _two_lines(label: str) -> str:
    """Put the unit of a y label on its own line ("range [m]" -> "range\\n[m]"), so that
    stacked panels keep their labels apart at any font size."""
    return label.replace(" [", "\n[", 1) if " [" in label else label


def _break_at_wraps(t, y):
    """Insert a NaN where a wrapped angle jumps by more than pi, so that a line drawn through the
    samples stops at the jump instead of crossing the panel with a vertical stroke."""
    t, y = np.asarray(t, float), np.asarray(y, float)
    with np.errstate(invalid="ignore"):
        idx = np.flatnonzero(np.abs(np.diff(y)) > np.pi) + 1
    return np.insert(t, idx, np.nan), np.insert(y, idx, np.nan)


def _take_legend(fig):
    """Remove every legend of ``fig`` (panels and figure); return the handles and names of the
    first panel's series."""
    for ax in fig.axes:
        if ax.get_legend() is not None:
            ax.get_legend().remove()
    for leg in list(fig.legends):
        leg.remove()
    return fig.axes[0].get_legend_handles_labels()


def _place_legend(fig, axes, n: int):
    """One legend for the whole grid of panels, never over the data: in the first unused panel when
    the grid has one, otherwise below the panels.  A single series gets no legend
    (the title names it)."""
    handles, names = _take_legend(fig)
    if len(handles) < 2:
        return
    if n < axes.size:
        axes.flat[n].legend(handles, names, loc="center", frameon=False)
    else:
        fig.legend(handles, names, loc="outside lower center", ncol=len(handles), frameon=False)


def plot_series(t, series: dict, labels, title: str, styles: dict | None = None, ncols: int = 2, figsize=None,
                wrapped=()):
    """One panel per component: ``series`` maps a legend name to an array (K, n).

    ``labels`` are the n y-axis labels (with units); ``styles`` maps a legend name to
    keyword arguments of ``Axes.plot``; ``figsize`` in inches (default 11 x 2.3 per row);
    ``wrapped`` lists the components that are wrapped angles (their lines break at the +-pi jumps).
    The legend sits in an unused panel or above the panels; the lowest panel of each column
    carries the time axis.
    """
    n = len(labels)
    nrows = int(np.ceil(n / ncols))
    fig, axes = plt.subplots(nrows, ncols, figsize=figsize or (11, 2.3 * nrows), sharex=True, squeeze=False,
                             layout="constrained")
    styles = styles or {}
    for i, ax in enumerate(axes.flat):
        if i >= n:
            ax.set_axis_off()
            continue
        for name, arr in series.items():
            col = np.asarray(arr)[:, i]
            tt, yy = _break_at_wraps(t, col) if i in wrapped else (t, col)
            ax.plot(tt, yy, label=name, **styles.get(name, {"lw": line_width(0.7)}))
        ax.set_ylabel(_two_lines(labels[i]))
        ax.grid(True, alpha=0.3)
    for c in range(ncols):
        used = [r for r in range(nrows) if r * ncols + c < n]
        if used:
            axes[used[-1], c].xaxis.set_tick_params(labelbottom=True)
            axes[used[-1], c].set_xlabel("time $t$ [s]")
    fig.suptitle(title)
    _place_legend(fig, axes, n)
    return fig


def legend_below(fig):
    """Put the one legend of a :func:`plot_series` figure (``plot_states``, ``plot_errors``,
    ``plot_measurements``) in one row below all panels, where it covers no data, whatever panel it
    was in.  Returns the figure legend (None for a single series, which has no legend)."""
    handles, labels = _take_legend(fig)
    if len(handles) < 2:
        return None
    if fig.get_layout_engine() is not None and "Constrained" in type(fig.get_layout_engine()).__name__:
        return fig.legend(handles, labels, loc="outside lower center", ncol=len(labels), frameon=False,
                          markerscale=3)
    return fig.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0.0), ncol=len(labels),
                      frameon=False, markerscale=3)


def plot_states(t, x, sigma2=None, truth=None, title: str = "States", figsize=None, ncols: int = 2,
                names=("estimate", "truth")):
    """States (K, 6) with an optional +-2 sigma band (K, 6) and the truth (K, 6); ``ncols`` panels per row;
    ``names`` are the legend names of ``x`` (solid) and ``truth`` (dashed)."""
    est, tru = names
    series = {est: x}
    styles = {est: {"lw": line_width(0.7), "color": "C0"}, tru: {"lw": line_width(0.7), "color": "k", "ls": "--"}}
    if truth is not None:
        series[tru] = truth
    fig = plot_series(t, series, STATE_LABELS, title, styles, ncols=ncols, figsize=figsize)
    if sigma2 is not None:
        for i, ax in enumerate(fig.axes[:6]):
            ax.fill_between(t, x[:, i] - sigma2[:, i], x[:, i] + sigma2[:, i], color="C0", alpha=0.2,
                            label=r"$\pm 2\sigma$")
        _place_legend(fig, np.array(fig.axes[:6]), 6)
    return fig


def plot_errors(t, errors, sigma2, title: str = r"Estimation errors with $\pm 2\sigma$ bounds", figsize=None,
                ncols: int = 2):
    """Errors (K, 6) (headings wrapped) against +-2 sigma (K, 6); ``ncols`` panels per row."""
    bound = {"lw": line_width(0.7), "color": "k", "ls": "--"}
    # one legend entry for both bound lines: a name starting with "_" is left out of the legend
    styles = {"error": {"lw": line_width(0.7), "color": "C3"}, r"$\pm 2\sigma$": bound, "_-2sigma": bound}
    labels = [f"error {lab}" for lab in STATE_LABELS]
    return plot_series(t, {"error": errors, r"$\pm 2\sigma$": sigma2, "_-2sigma": -np.asarray(sigma2)},
                       labels, title, styles, ncols=ncols, figsize=figsize)


def plot_measurements(t, series: dict, title: str = "Measurements", figsize=None, ncols: int = 2):
    """Measurements: ``series`` maps a legend name to an array (K, 5) (NaN rows are gaps);
    ``ncols`` panels per row.  The first series is drawn as dots, the others as lines that break
    where a wrapped bearing jumps by 2 pi (no vertical strokes)."""
    ms = 0.35 * mpl.rcParams["lines.markersize"]
    styles = {name: ({"lw": 0, "marker": ".", "ms": ms} if i == 0 else {"lw": line_width(0.7)})
              for i, name in enumerate(series)}
    return plot_series(t, series, MEAS_LABELS, title, styles, ncols=ncols, figsize=figsize, wrapped=(0, 2))


def plot_consistency(mc, title: str | None = None, figsize=None):
    """Run-averaged NEES and NIS of a :class:`~kfcal_helpers.coop.montecarlo.MonteCarloResult`
    against their chi-square bounds (default 11 x 3.2 in)."""
    fig, axes = plt.subplots(1, 2, figsize=figsize or (11, 3.2))
    for ax, mean, bounds, name in ((axes[0], mc.nees_mean, mc.nees_bounds, "NEES"),
                                   (axes[1], mc.nis_mean, mc.nis_bounds, "NIS")):
        ok = np.isfinite(mean)
        ax.plot(mc.t[ok], mean[ok], ".", ms=0.35 * mpl.rcParams["lines.markersize"],
                label=f"{name}, mean of {mc.n_runs} runs")
        for b, lab in zip(bounds, (f"χ² bounds, α = {mc.alpha:g}", None)):
            ax.axhline(b, color="k", ls="--", lw=line_width(0.7), label=lab)
        ax.set_xlabel("time $t$ [s]")
        ax.set_ylabel(f"mean {name} [-]")
        frac = mc.nees_inside_fraction if name == "NEES" else mc.nis_inside_fraction
        ax.set_title(f"{name}: {100 * frac:.1f}% inside [{bounds[0]:.2f}, {bounds[1]:.2f}]")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right")
    fig.suptitle(title or f"{mc.filter.upper()} truth-model test, significance {mc.alpha:g}")
    fig.tight_layout()
    return fig


def plot_paths(paths: dict, title: str = "Paths of the two vehicles", figsize=None):
    """Paths in the east-north plane: ``paths`` maps a legend name to states (K, 6).  The UGV is
    drawn in C0, the UAV in C1, one line style per entry, starts as dots; equal axis scales, and an
    inset zoomed on the UGV (its circle is small next to the UAV's); default 7 x 6 in."""
    styles = ("-", "--", ":", "-.")
    fig, ax = plt.subplots(figsize=figsize or (7, 6))
    zoom = ax.inset_axes([0.36, 0.3, 0.3, 0.4])
    for i, (name, x) in enumerate(paths.items()):
        x = np.asarray(x)
        ls = styles[i % len(styles)]
        for target in (ax, zoom):
            _ = target.plot(x[:, 0], x[:, 1], ls, color="C0", label=f"UGV, {name}")
            _ = target.plot(x[0, 0], x[0, 1], "o", color="C0")
        _ = ax.plot(x[:, 3], x[:, 4], ls, color="C1", label=f"UAV, {name}")
        _ = ax.plot(x[0, 3], x[0, 4], "o", color="C1")
    ax.set_xlabel(r"east $\xi$ [m]")
    ax.set_ylabel(r"north $\eta$ [m]")
    ax.set_aspect("equal", adjustable="datalim")
    zoom.set_aspect("equal", adjustable="datalim")
    zoom.set_title("UGV, zoomed [m]", fontsize="medium")
    zoom.tick_params(labelsize="small")
    ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0))
    ax.set_title(title)
    fig.tight_layout()
    return fig


def plot_nis_comparison(averages: dict, bounds, title: str = "Time-averaged NIS on the log",
                        expected: float = N_MEAS, figsize=None):
    """Time-averaged NIS per filter (``averages`` maps a name to a float) against the chi-square
    ``bounds`` (lower, upper) of a consistent filter and the ``expected`` value (the measurement
    dimension); a marker per filter, green inside the bounds, red outside; linear scale
    spanning the bounds and the values (default 7 x 4.5 in)."""
    names = list(averages)
    values = np.array([averages[n] for n in names], float)
    lo, hi = bounds
    fig, ax = plt.subplots(figsize=figsize or (7, 4.5))
    ax.axhspan(lo, hi, color="C2", alpha=0.25, label=f"χ² bounds [{lo:.2f}, {hi:.2f}]")
    _ = ax.axhline(expected, color="k", ls="--", lw=line_width(0.7), label=f"expected value {expected:g}")
    x = np.arange(len(names))
    for xi, v in zip(x, values):
        inside = lo <= v <= hi
        _ = ax.plot(xi, v, "o", ms=2 * mpl.rcParams["lines.markersize"], color="C2" if inside else "C3")
        ax.annotate(f"{v:.2f} ({'inside' if inside else 'outside'})", (xi, v), xytext=(0, 12),
                    textcoords="offset points", ha="center")
    ax.set_xticks(x, names)
    ax.set_xlim(-0.5, len(names) - 0.5)
    bottom, top = min(values.min(), lo), max(values.max(), hi)
    pad = 0.25 * (top - bottom)
    ax.set_ylim(bottom - pad, top + 2 * pad)   # linear: the band and the values fill the axis
    ax.set_ylabel("time-averaged NIS [-]")
    ax.set_title(title)
    ax.legend(loc="upper right")
    ax.grid(False, axis="x")
    fig.tight_layout()
    return fig


def plot_runs_consistency(mc, title: str | None = None, figsize=None, ylim=None):
    """Every run's NEES and NIS per step (small grey points), their run averages (line) and the
    chi-square bounds of the average (dashed) for a
    :class:`~kfcal_helpers.coop.montecarlo.MonteCarloResult`; log y scale (default 11 x 3.6 in)."""
    fig, axes = plt.subplots(1, 2, figsize=figsize or (11, 3.6), layout="constrained")
    ms = 0.15 * mpl.rcParams["lines.markersize"]
    for ax, values, mean, bounds, name in ((axes[0], mc.nees, mc.nees_mean, mc.nees_bounds, "NEES"),
                                           (axes[1], mc.nis, mc.nis_mean, mc.nis_bounds, "NIS")):
        ok = np.isfinite(mean)
        tt = np.broadcast_to(mc.t, values.shape)[:, ok]
        _ = ax.plot(tt.ravel(), values[:, ok].ravel(), ".", ms=ms, color="0.6", alpha=0.3, rasterized=True,
                    label=f"each of the {mc.n_runs} runs")
        _ = ax.plot(mc.t[ok], mean[ok], "-", color="C0", lw=line_width(0.8), label=f"average of {mc.n_runs} runs")
        for b, lab in zip(bounds, (f"χ² bounds of the average, significance {mc.alpha:g}", None)):
            _ = ax.axhline(b, color="k", ls="--", lw=line_width(0.8), label=lab)
        ax.set_yscale("log")
        if ylim is not None:
            ax.set_ylim(*ylim)
        ax.set_xlabel("time $t$ [s]")
        ax.set_ylabel(f"{name} [-]")
        frac = mc.nees_inside_fraction if name == "NEES" else mc.nis_inside_fraction
        ax.set_title(f"{name}: average inside [{bounds[0]:.2f}, {bounds[1]:.2f}] at {100 * frac:.1f}% of steps")
        ax.grid(True, alpha=0.3)
    # one legend below both panels: inside either it would hide run points
    fig.legend(*axes[0].get_legend_handles_labels(), loc="outside lower center", ncol=3, markerscale=6,
               frameon=False)
    fig.suptitle(title or f"{mc.filter.upper()} truth-model test, significance {mc.alpha:g}")
    return fig
